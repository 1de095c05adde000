//! Finding, checking and (if needed) building the node firmware ELFs: `cargo fw` puts them in
//! `target/avr-none/fw/{anchor,agent,sink}-fw.elf` of the hoploc workspace.
//!
//! Where hoploc looks (`hoploc --help` says the same):
//! * the **workspace** is the first directory, from the current one upwards, with a `Cargo.toml`
//!   that has a `[workspace]` table and a `scenarios/` directory beside it ([`workspace`]): the
//!   hoploc source tree the command runs in, wherever the binary was built or copied to;
//! * **firmware**: `--firmware-dir`, else `$HOPLOC_FIRMWARE_DIR`, else the workspace's
//!   `target/avr-none/fw`, else `target/avr-none/fw` of the current directory ([`default_dir`]);
//! * **scenarios**: a path given on the command line, else `scenarios/NAME.toml` of the
//!   workspace, else of the current directory (`crate::scenario::resolve`).
//!
//! Before a firmware runs, [`check`] makes sure the file is a whole AVR ELF of the expected
//! role, and says what is wrong (naming the file) when it is not: a truncated copy, another
//! file, or another role's firmware.

use std::path::{Path, PathBuf};
use std::process::Command;

use loc_proto::config::Config;
pub use loc_proto::Role;
use simavr::Avr;

/// The cargo package (and ELF name) of `role`'s firmware: `anchor-fw`, `agent-fw`, `sink-fw`.
pub fn crate_name(role: Role) -> String {
    format!("{}-fw", role.name())
}

/// The hoploc workspace at or above `start`: the first directory with a `Cargo.toml` holding a
/// `[workspace]` table and a `scenarios/` directory.
pub fn workspace_from(start: &Path) -> Option<PathBuf> {
    start.ancestors().find_map(|dir| {
        let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).ok()?;
        let is_workspace = manifest.lines().any(|l| l.trim() == "[workspace]");
        (is_workspace && dir.join("scenarios").is_dir()).then(|| dir.to_path_buf())
    })
}

/// The hoploc workspace the command runs in ([`workspace_from`] the current directory).
pub fn workspace() -> Option<PathBuf> {
    workspace_from(&std::env::current_dir().ok()?)
}

/// Where `cargo fw` puts the ELFs: `$HOPLOC_FIRMWARE_DIR` if set, else `target/avr-none/fw` of
/// the [`workspace`], else of the current directory.
pub fn default_dir() -> PathBuf {
    std::env::var_os("HOPLOC_FIRMWARE_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().unwrap_or_default().join("target/avr-none/fw"))
}

/// The ELF of `role` in `dir`.
pub fn elf(dir: &Path, role: Role) -> PathBuf {
    dir.join(format!("{}.elf", crate_name(role)))
}

/// Builds the firmware with `cargo fw` in the [`workspace`] when an ELF is missing from the
/// default location; elsewhere, or outside a workspace, says what is missing and how to get it.
pub fn ensure_built(dir: &Path) -> Result<(), String> {
    let missing: Vec<String> = Role::ALL
        .iter()
        .map(|&r| elf(dir, r))
        .filter(|p| !p.exists())
        .map(|p| p.display().to_string())
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let ws = workspace();
    let Some(ws) = ws.filter(|_| dir == default_dir()) else {
        return Err(format!(
            "no firmware ELF {}: build them with `cargo fw` in the hoploc workspace (run hoploc \
             there, or give --firmware-dir or HOPLOC_FIRMWARE_DIR)",
            missing.join(", ")
        ));
    };
    eprintln!("building the firmware (cargo fw in {})...", ws.display());
    let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .arg("fw")
        .current_dir(&ws)
        .status()
        .map_err(|e| format!("could not run cargo fw: {e}"))?;
    if !status.success() {
        return Err("cargo fw failed".into());
    }
    Ok(())
}

/// The role a firmware image is for: its built-in config (`.eeprom`) says it; without one, its
/// symbols (each node firmware's code lives in its crate, `anchor_fw`, `agent_fw`, `sink_fw`).
pub fn role_of(image: &simavr::elf::ElfImage) -> Option<Role> {
    if let Some(config) = image
        .eeprom
        .as_deref()
        .and_then(|b| Config::from_bytes(b).ok())
    {
        return Some(config.role);
    }
    let mangled = |r: Role| {
        let name = format!("{}_fw", r.name());
        format!("{}{name}", name.len())
    };
    let found: Vec<Role> = Role::ALL
        .into_iter()
        .filter(|&r| {
            let m = mangled(r);
            image.symbols.iter().any(|s| s.contains(&m))
        })
        .collect();
    match found[..] {
        [role] => Some(role),
        _ => None,
    }
}

/// Checks that `path` is a whole AVR ELF of `role`'s firmware; the error names the file and
/// the problem.
pub fn check(path: &Path, role: Role) -> Result<(), String> {
    let image = simavr::elf::inspect(path).map_err(|e| match e {
        simavr::Error::BadElf(..) => e.to_string(),
        e => format!("{}: {e}", path.display()),
    })?;
    match role_of(&image) {
        Some(r) if r == role => Ok(()),
        Some(r) => Err(format!(
            "{}: the {} firmware, not the {} firmware this node needs ({} builds it)",
            path.display(),
            r.name(),
            role.name(),
            crate_name(role)
        )),
        None => Err(format!(
            "{}: not a hoploc node firmware (no node config in its .eeprom and no {} code): the \
             {} firmware is needed",
            path.display(),
            crate_name(role),
            role.name()
        )),
    }
}

/// Loads `role`'s firmware at `path` in simavr, after [`check`].
pub fn load(path: &Path, role: Role) -> Result<Avr, String> {
    check(path, role)?;
    Avr::load(path).map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_is_found_from_below_and_not_elsewhere() {
        let tmp = std::env::temp_dir().join(format!("hoploc-ws-{}", std::process::id()));
        let deep = tmp.join("ws/a/b");
        std::fs::create_dir_all(&deep).unwrap();
        std::fs::create_dir_all(tmp.join("ws/scenarios")).unwrap();
        std::fs::write(tmp.join("ws/Cargo.toml"), "[workspace]\nmembers = []\n").unwrap();
        // A member crate's manifest on the way up is not the workspace.
        std::fs::write(tmp.join("ws/a/Cargo.toml"), "[package]\nname = \"a\"\n").unwrap();
        assert_eq!(workspace_from(&deep), Some(tmp.join("ws")));
        assert_eq!(workspace_from(&tmp), None);
        std::fs::remove_dir_all(&tmp).unwrap();
    }

    #[test]
    fn the_role_comes_from_the_config_or_the_symbols() {
        let mut buf = [0; 32];
        let sink = Config {
            role: Role::Sink,
            ..Config::DEFAULT
        };
        let n = sink.to_bytes(&mut buf).unwrap();
        let image = simavr::elf::ElfImage {
            eeprom: Some(buf[..n].to_vec()),
            symbols: vec!["_ZN9anchor_fw3run17h0123456789abcdefE".into()],
        };
        assert_eq!(role_of(&image), Some(Role::Sink));
        let symbols_only = simavr::elf::ElfImage {
            eeprom: None,
            ..image.clone()
        };
        assert_eq!(role_of(&symbols_only), Some(Role::Anchor));
        assert_eq!(role_of(&simavr::elf::ElfImage::default()), None);
    }
}
