//! `cargo run` for users, as far as it goes without a board: in each firmware crate it runs that
//! firmware (not one of the size probes), through `scripts/flash-uno` (the cargo runner), which
//! checks the ELF's size, finds the port and hands the ELF to avrdude for the Uno's bootloader;
//! and the `Ravedude.toml` each firmware crate has for those who run `ravedude` instead. The
//! README's flashing commands themselves run in `readme_flash.rs`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hoploc_tests::firmware_elf;
use loc_proto::Role;

/// The firmware crates.
const FIRMWARE: [&str; 3] = ["anchor-fw", "agent-fw", "sink-fw"];

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// `cargo run` in a crate's directory runs the binary `default-run` names, or its only one;
/// binaries behind `required-features` still count (cargo then asks which one to run).
#[test]
fn cargo_run_in_each_firmware_crate_runs_its_firmware() {
    let out = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args(["metadata", "--no-deps", "--format-version", "1"])
        .current_dir(workspace_root())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for name in FIRMWARE {
        let pkg = meta["packages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("no package {name}"));
        let bins: Vec<&str> = pkg["targets"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|t| t["kind"].as_array().unwrap().iter().any(|k| k == "bin"))
            .map(|t| t["name"].as_str().unwrap())
            .collect();
        let runs = match pkg["default_run"].as_str() {
            Some(bin) => bin,
            None if bins.len() == 1 => bins[0],
            None => panic!("{name}: `cargo run` cannot tell which of {bins:?} to run"),
        };
        assert_eq!(runs, name, "{name}: `cargo run` runs {runs}");
    }
}

/// Runs `scripts/flash-uno elf` with `path` first on `PATH` and the environment `env`.
fn flash_uno(elf: &Path, path: &Path, env: &[(&str, &str)]) -> Output {
    let path = format!("{}:/usr/bin:/bin", path.display());
    let mut cmd = Command::new(workspace_root().join("scripts/flash-uno"));
    cmd.arg(elf).env("PATH", path).env_remove("HOPLOC_PORT");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().unwrap()
}

/// A directory of stand-ins: `avrdude` writes its arguments, one a line, to `avrdude.args`
/// beside itself; with `big`, `avr-size` reports an ELF larger than the Uno's flash.
fn stand_ins(big: bool) -> tempdir::Dir {
    let dir = tempdir::Dir::new();
    dir.script(
        "avrdude",
        &format!(
            "#!/bin/sh\nfor a in \"$@\"; do echo \"$a\"; done > {}\n",
            dir.path().join("avrdude.args").display()
        ),
    );
    if big {
        dir.script(
            "avr-size",
            "#!/bin/sh\necho '   text\t   data\t    bss\t    dec\t    hex\tfilename'\n\
             echo '  32300\t     40\t    100\t  32440\t   7eb8\tx.elf'\n",
        );
    }
    dir
}

#[test]
fn flash_uno_hands_the_elf_to_avrdude_for_the_uno_bootloader() {
    let elf = firmware_elf(Role::Anchor);
    let dir = stand_ins(false);
    let port = dir.path().join("ttyACM9");
    std::fs::write(&port, b"").unwrap();
    let out = flash_uno(&elf, dir.path(), &[("HOPLOC_PORT", port.to_str().unwrap())]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("anchor-fw.elf: flash "), "{stderr}");
    let args = std::fs::read_to_string(dir.path().join("avrdude.args")).unwrap();
    let want = [
        "-c".to_string(),
        "arduino".into(),
        "-p".into(),
        "m328p".into(),
        "-b".into(),
        "115200".into(),
        "-P".into(),
        port.display().to_string(),
        "-D".into(),
        "-U".into(),
        format!("flash:w:{}:e", elf.display()),
    ];
    assert_eq!(args.lines().collect::<Vec<_>>(), want);
}

#[test]
fn flash_uno_without_a_board_says_so_and_flashes_nothing() {
    let elf = firmware_elf(Role::Sink);
    let dir = stand_ins(false);
    let out = flash_uno(
        &elf,
        dir.path(),
        &[("HOPLOC_PORT", "/dev/hoploc-no-such-port")],
    );
    assert_eq!(out.status.code(), Some(3));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("does not exist: is the Uno plugged in?"),
        "{stderr}"
    );
    assert!(!dir.path().join("avrdude.args").exists());
}

#[test]
fn flash_uno_refuses_an_elf_larger_than_the_flash() {
    let elf = firmware_elf(Role::Agent);
    let dir = stand_ins(true);
    let port = dir.path().join("ttyACM9");
    std::fs::write(&port, b"").unwrap();
    let out = flash_uno(&elf, dir.path(), &[("HOPLOC_PORT", port.to_str().unwrap())]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("does not fit"), "{stderr}");
    assert!(!dir.path().join("avrdude.args").exists());
}

/// Without `HOPLOC_PORT`, the only serial port there is (here in a stand-in /dev:
/// `FLASH_UNO_DEV`); with two, flash-uno names them and flashes nothing. `HOPLOC_PORT=/dev/…`
/// names a port in the stand-in /dev too.
#[test]
fn flash_uno_takes_the_only_port_and_will_not_choose_among_several() {
    let elf = firmware_elf(Role::Sink);
    let dir = stand_ins(false);
    let dev = dir.path().join("dev");
    std::fs::create_dir(&dev).unwrap();
    let dev_env = ("FLASH_UNO_DEV", dev.to_str().unwrap());
    let port_of = |dir: &tempdir::Dir| {
        let args = std::fs::read_to_string(dir.path().join("avrdude.args")).unwrap();
        let args: Vec<&str> = args.lines().collect();
        let p = args.iter().position(|&a| a == "-P").unwrap();
        PathBuf::from(args[p + 1])
    };

    let out = flash_uno(&elf, dir.path(), &[dev_env]);
    assert_eq!(out.status.code(), Some(3));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no Arduino Uno found"), "{stderr}");

    std::fs::write(dev.join("ttyUSB0"), b"").unwrap();
    let out = flash_uno(&elf, dir.path(), &[dev_env]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(port_of(&dir), dev.join("ttyUSB0"));

    std::fs::write(dev.join("ttyACM0"), b"").unwrap();
    std::fs::remove_file(dir.path().join("avrdude.args")).unwrap();
    let out = flash_uno(&elf, dir.path(), &[dev_env]);
    assert_eq!(out.status.code(), Some(3));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("several serial ports found"), "{stderr}");
    assert!(!dir.path().join("avrdude.args").exists());

    let out = flash_uno(
        &elf,
        dir.path(),
        &[dev_env, ("HOPLOC_PORT", "/dev/ttyACM0")],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(port_of(&dir), dev.join("ttyACM0"));
}

/// Each firmware crate's `Ravedude.toml`: the Uno, and a console at the nodes' UART rate.
#[test]
fn each_firmware_crate_has_a_ravedude_config_for_the_uno() {
    for name in FIRMWARE {
        let path = workspace_root().join(name).join("Ravedude.toml");
        let text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let cfg: toml::Table = toml::from_str(&text).unwrap();
        let general = cfg["general"].as_table().unwrap();
        assert_eq!(general["board"].as_str(), Some("uno"), "{name}");
        assert_eq!(general["open-console"].as_bool(), Some(true), "{name}");
        assert_eq!(
            general["serial-baudrate"].as_integer(),
            Some(i64::from(uno_board::DEFAULT_BAUD)),
            "{name}"
        );
    }
}

/// A temporary directory, removed when dropped.
mod tempdir {
    use std::os::unix::fs::PermissionsExt;
    use std::path::{Path, PathBuf};
    use std::sync::atomic::{AtomicUsize, Ordering};

    pub struct Dir(PathBuf);

    impl Dir {
        pub fn new() -> Dir {
            static N: AtomicUsize = AtomicUsize::new(0);
            let p = std::env::temp_dir().join(format!(
                "hoploc-flash-{}-{}",
                std::process::id(),
                N.fetch_add(1, Ordering::Relaxed)
            ));
            std::fs::create_dir_all(&p).unwrap();
            Dir(p)
        }

        pub fn path(&self) -> &Path {
            &self.0
        }

        /// An executable `name` in the directory with `body`.
        pub fn script(&self, name: &str, body: &str) {
            let p = self.0.join(name);
            std::fs::write(&p, body).unwrap();
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
    }

    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}
