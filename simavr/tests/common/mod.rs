//! Builds the C test fixtures with avr-gcc (fails loudly if avr-gcc is missing).

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

static BUILD: Mutex<()> = Mutex::new(());

/// Compiles `tests/fixtures/<name>.c` for the ATmega328P and returns the ELF path.
pub fn fixture(name: &str) -> PathBuf {
    let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let src = dir.join(format!("{name}.c"));
    let out_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("simavr-fixtures");
    std::fs::create_dir_all(&out_dir).expect("create fixture output dir");
    let elf = out_dir.join(format!("{name}.elf"));
    let newest_src = std::fs::read_dir(&dir)
        .expect("fixtures dir")
        .filter_map(|e| e.ok()?.metadata().ok()?.modified().ok())
        .max();
    let fresh = match (
        std::fs::metadata(&elf).and_then(|m| m.modified()),
        newest_src,
    ) {
        (Ok(e), Some(s)) => e > s,
        _ => false,
    };
    if fresh {
        return elf;
    }
    let result = Command::new("avr-gcc")
        .args(["-mmcu=atmega328p", "-Os", "-DF_CPU=16000000UL", "-g"])
        .args(["-Wall", "-Wextra", "-Wno-unused-function", "-Werror"])
        .arg("-o")
        .arg(&elf)
        .arg(&src)
        .output();
    match result {
        Err(e) => panic!(
            "cannot run avr-gcc ({e}): the simavr tests need it to build their fixtures; \
             install gcc-avr and avr-libc (apt-get install gcc-avr avr-libc)"
        ),
        Ok(o) if !o.status.success() => panic!(
            "avr-gcc failed on {}:\n{}",
            src.display(),
            String::from_utf8_lossy(&o.stderr)
        ),
        Ok(_) => elf,
    }
}
