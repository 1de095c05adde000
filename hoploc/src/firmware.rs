//! Finding (and if needed building) the node firmware ELFs: `cargo fw` puts them in
//! `target/avr-none/fw/{anchor,agent,sink}-fw.elf`.

use std::path::{Path, PathBuf};
use std::process::Command;

pub use loc_proto::Role;

/// The cargo package (and ELF name) of `role`'s firmware: `anchor-fw`, `agent-fw`, `sink-fw`.
pub fn crate_name(role: Role) -> String {
    format!("{}-fw", role.name())
}

/// The workspace root this binary was built from.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// Where `cargo fw` puts the ELFs, unless `HOPLOC_FIRMWARE_DIR` says otherwise.
pub fn default_dir() -> PathBuf {
    std::env::var_os("HOPLOC_FIRMWARE_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target/avr-none/fw"))
}

/// The ELF of `role` in `dir`.
pub fn elf(dir: &Path, role: Role) -> PathBuf {
    dir.join(format!("{}.elf", crate_name(role)))
}

/// Builds the firmware with `cargo fw` when an ELF is missing from the default location.
pub fn ensure_built(dir: &Path) -> Result<(), String> {
    if Role::ALL.iter().all(|&r| elf(dir, r).exists()) {
        return Ok(());
    }
    if dir != default_dir() {
        return Err(format!("no firmware ELFs in {}", dir.display()));
    }
    eprintln!("building the firmware (cargo fw)...");
    let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .arg("fw")
        .current_dir(workspace_root())
        .status()
        .map_err(|e| format!("could not run cargo fw: {e}"))?;
    if !status.success() {
        return Err("cargo fw failed".into());
    }
    Ok(())
}
