//! The README's flashing commands, run as a user types them. Every fenced block of `README.md`
//! that flashes a board (`cargo run` in a firmware crate, `cargo fw-run -p …`) runs whole, in one
//! `bash -e` session that starts at the workspace root (a `cd` carries to the next line; a
//! failing command stops the block, one before `&&` leaves a flash missing), with stand-ins for
//! what is not on a build machine:
//! `avrdude` and `ravedude` on `PATH` record their arguments and keep the ELF they were given,
//! and the serial ports are empty files in a directory `scripts/flash-uno` takes for `/dev`
//! (`FLASH_UNO_DEV`). Each flash must hand over the ELF of the role the command names, built
//! with the config its `HOPLOC_*` variables give, to avrdude for the Uno's bootloader on the
//! port the command picks (or the only one there is), or to ravedude where the command says so.
//!
//! The commands build in the workspace's target directory, where the simavr tests take the
//! ELFs of `cargo fw` from: a directory of their own would cost one more full firmware build
//! (`core` and every crate in the `fw` profile, which `cargo fw` has built there already) on
//! every fresh checkout. A README command may rebuild `target/avr-none/fw/*.elf`
//! with a config of its own (`HOPLOC_ID=2 cargo fw-run -p …`), so after each block `cargo fw`
//! builds them back with the built-in defaults; blocks run one at a time.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};
use std::process::Command;

use hoploc::firmware::crate_name;
use loc_proto::config::{from_env, Config, ENV_VARS};
use loc_proto::Role;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// A fenced block of the README: the heading it is under, its first line's number, its lines
/// (without the fence's indentation).
#[derive(Clone, Debug)]
struct Block {
    heading: String,
    line: usize,
    lines: Vec<String>,
}

/// Every fenced block of `markdown`, in order.
fn fenced_blocks(markdown: &str) -> Vec<Block> {
    let mut blocks = Vec::new();
    let mut heading = String::new();
    let mut open: Option<(usize, Block)> = None;
    for (i, line) in markdown.lines().enumerate() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        if trimmed.starts_with("```") {
            match open.take() {
                Some((_, block)) => blocks.push(block),
                None => {
                    open = Some((
                        indent,
                        Block {
                            heading: heading.clone(),
                            line: i + 2,
                            lines: Vec::new(),
                        },
                    ))
                }
            }
        } else if let Some((indent, block)) = &mut open {
            let cut = line.len().min(*indent);
            block.lines.push(line[cut..].to_string());
        } else if trimmed.starts_with('#') && indent == 0 {
            heading = trimmed.trim_start_matches('#').trim().to_string();
        }
    }
    blocks
}

/// Which program a flash hands the ELF to.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Runner {
    /// `scripts/flash-uno`, the cargo runner of `.cargo/config.toml`: avrdude.
    FlashUno,
    /// `CARGO_TARGET_AVR_NONE_RUNNER=ravedude`.
    Ravedude,
}

/// A flashing command as a user reads it: which firmware it builds with which variables, and
/// where the ELF goes.
#[derive(Clone, Debug)]
struct Flash {
    /// The README line.
    text: String,
    role: Role,
    /// `target/avr-none/<this>/`: `debug` for `cargo run` in a crate, `fw` for `cargo fw-run`.
    profile: &'static str,
    /// The variables the line sets (`NAME=value` before `cargo`).
    vars: BTreeMap<String, String>,
    runner: Runner,
}

impl Flash {
    /// The config the firmware must carry: the line's `HOPLOC_*` variables, the rest default.
    fn config(&self) -> Result<Config, String> {
        from_env(self.role, |name| self.vars.get(name)).map_err(|e| format!("{}: {e}", e.var))
    }
}

/// The firmware crate directory `dir` (relative to the workspace root) is, if any.
fn role_of_dir(dir: &Path) -> Option<Role> {
    Role::ALL
        .into_iter()
        .find(|&r| dir == Path::new(&crate_name(r)))
}

fn role_of_crate(name: &str) -> Option<Role> {
    Role::ALL.into_iter().find(|&r| crate_name(r) == name)
}

/// The cargo commands a flashing block may hold besides its flashes: builds. (Anything else, an
/// install say, the test would rather not run.)
const BUILDS: [&str; 3] = ["build", "fw", "fw-build"];

/// The flashes of `block` in order, read as a user reads them: `cd DIR` moves (from the
/// workspace root), `NAME=value … cargo run` in a firmware crate's directory and
/// `cargo fw-run -p CRATE` flash, `cargo run -p` a host program does not. A block that flashes
/// must hold nothing else but builds: a line with another command (`export`, a pipe, `cargo
/// install`) is an error, for this reading would not know what it does.
fn flashes(block: &Block) -> Result<Vec<Flash>, String> {
    let mut cwd = PathBuf::new();
    let mut out = Vec::new();
    let mut unknown = Vec::new();
    for line in &block.lines {
        // A comment starts with a `#` at a word's start.
        let comment = line
            .char_indices()
            .find(|&(i, c)| c == '#' && (i == 0 || line[..i].ends_with(char::is_whitespace)));
        let code = comment.map_or(line.as_str(), |(i, _)| &line[..i]);
        for segment in code.split("&&").map(str::trim).filter(|s| !s.is_empty()) {
            let words: Vec<&str> = segment.split_whitespace().collect();
            if words[0] == "cd" && words.len() == 2 {
                for c in Path::new(words[1]).components() {
                    match c {
                        Component::ParentDir if cwd.pop() => {}
                        Component::Normal(n) => cwd.push(n),
                        Component::CurDir => {}
                        _ => unknown.push(format!("{line:?}: `cd` out of the workspace")),
                    }
                }
                continue;
            }
            let split = words
                .iter()
                .position(|w| !w.contains('='))
                .unwrap_or(words.len());
            let vars: BTreeMap<String, String> = words[..split]
                .iter()
                .map(|w| {
                    let (k, v) = w.split_once('=').unwrap();
                    (k.to_string(), v.to_string())
                })
                .collect();
            let (cmd, sub, args) = match &words[split..] {
                ["cargo", sub, args @ ..] => ("cargo", *sub, args),
                [cmd, ..] => (*cmd, "", &[][..]),
                [] => ("", "", &[][..]),
            };
            let package = args
                .iter()
                .position(|&a| a == "-p" || a == "--package")
                .and_then(|i| args.get(i + 1).copied());
            let (role, profile) = match (cmd, sub, package) {
                ("cargo", "fw-run", Some(p)) => match role_of_crate(p) {
                    Some(role) => (role, "fw"),
                    None => return Err(format!("{line:?}: {p} is no firmware crate")),
                },
                ("cargo", "fw-run", None) => return Err(format!("{line:?}: fw-run without -p")),
                ("cargo", "run", Some(p)) if role_of_crate(p).is_none() => {
                    unknown.push(format!("{line:?}: runs the host program {p}"));
                    continue;
                }
                ("cargo", "run", p) => match p.and_then(role_of_crate).or(role_of_dir(&cwd)) {
                    Some(role) => (role, "debug"),
                    None => return Err(format!("{line:?}: `cargo run` in {cwd:?}: no firmware")),
                },
                ("cargo", sub, _) if BUILDS.contains(&sub) => continue,
                _ => {
                    unknown.push(format!(
                        "{line:?}: `{segment}` is not a command this test knows"
                    ));
                    continue;
                }
            };
            let runner = match vars.get("CARGO_TARGET_AVR_NONE_RUNNER").map(String::as_str) {
                None => Runner::FlashUno,
                Some("ravedude") => Runner::Ravedude,
                Some(r) => return Err(format!("{line:?}: runner {r} unknown to this test")),
            };
            out.push(Flash {
                text: line.clone(),
                role,
                profile,
                vars,
                runner,
            });
        }
    }
    if !out.is_empty() && !unknown.is_empty() {
        return Err(unknown.join("\n"));
    }
    Ok(out)
}

/// The README's blocks that flash a board, with their flashes. Panics on a block this reading
/// cannot follow.
fn readme_flashing_blocks() -> Vec<(Block, Vec<Flash>)> {
    let readme = std::fs::read_to_string(workspace_root().join("README.md")).unwrap();
    fenced_blocks(&readme)
        .into_iter()
        .filter_map(|b| match flashes(&b) {
            Ok(f) if f.is_empty() => None,
            Ok(f) => Some((b, f)),
            Err(e) => panic!("README.md line {}: {e}", b.line),
        })
        .collect()
}

/// What a stand-in (avrdude or ravedude) was called with: its name, arguments, working
/// directory, and a copy of the ELF it was given.
#[derive(Debug)]
struct Call {
    tool: String,
    args: Vec<String>,
    cwd: PathBuf,
    elf: Option<Vec<u8>>,
}

/// A directory of the test's own, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> TempDir {
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let p = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!(
            "readme-flash-{}-{}",
            std::process::id(),
            N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The stand-in: records one call in `$rec/<n>/` (n = 0, 1, …) and copies the ELF named in
/// avrdude's `-U flash:w:FILE:e` or passed as ravedude's argument.
const RECORDER: &str = r#"#!/bin/sh
rec=$(dirname "$0")/calls
mkdir -p "$rec"
d=$rec/$(ls "$rec" | wc -l)
mkdir "$d"
basename "$0" > "$d/tool"
pwd > "$d/cwd"
: > "$d/args"
elf=
for a in "$@"; do
    printf '%s\n' "$a" >> "$d/args"
    case $a in
    flash:w:*:e) elf=${a#flash:w:}; elf=${elf%:e} ;;
    *.elf) elf=$a ;;
    esac
done
[ -z "$elf" ] || cp "$elf" "$d/elf"
"#;

/// A block's run: the stand-ins' calls, and the directory that stood for /dev.
struct Run {
    calls: Vec<Call>,
    dev: PathBuf,
}

/// Runs `block` through `bash -e` from the workspace root, with the stand-ins, the ports
/// `ports` (paths under /dev, made as empty files in the stand-in /dev) and the firmware built
/// in `target_dir`. Returns the stand-ins' calls, or bash's failure with its output.
fn run_block(block: &Block, ports: &[String], target_dir: &Path) -> Result<Run, String> {
    // One block at a time: two blocks building one firmware with two configs in one target
    // directory could each flash the other's ELF.
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = TempDir::new();
    let bin = tmp.0.join("bin");
    let dev = tmp.0.join("dev");
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::create_dir_all(&dev).unwrap();
    for tool in ["avrdude", "ravedude"] {
        use std::os::unix::fs::PermissionsExt;
        let p = bin.join(tool);
        std::fs::write(&p, RECORDER).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    for port in ports {
        std::fs::write(dev.join(port.strip_prefix("/dev/").unwrap()), b"").unwrap();
    }
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut cmd = Command::new("bash");
    cmd.args(["--noprofile", "--norc", "-e", "-c", &block.lines.join("\n")])
        .env("PATH", path)
        .env("FLASH_UNO_DEV", &dev);
    let out = users_shell(&mut cmd, target_dir).output().unwrap();
    // The simavr tests' ELFs with the built-in config again, whatever the block built.
    let restore = users_shell(&mut Command::new("cargo"), target_dir)
        .arg("fw")
        .output()
        .unwrap();
    assert!(
        restore.status.success(),
        "cargo fw after the block: {}",
        String::from_utf8_lossy(&restore.stderr)
    );
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(25).collect();
        return Err(format!(
            "README.md line {}: the block failed ({}):\n{}\n--- stderr, last lines:\n{}",
            block.line,
            out.status,
            block.lines.join("\n"),
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        ));
    }
    let calls = bin.join("calls");
    let n = std::fs::read_dir(&calls).map_or(0, |d| d.count());
    let calls = (0..n)
        .map(|i| {
            let d = calls.join(i.to_string());
            let read = |f: &str| std::fs::read_to_string(d.join(f)).unwrap();
            Call {
                tool: read("tool").trim().to_string(),
                args: read("args").lines().map(String::from).collect(),
                cwd: PathBuf::from(read("cwd").trim()),
                elf: std::fs::read(d.join("elf")).ok(),
            }
        })
        .collect();
    Ok(Run { calls, dev })
}

/// `cmd` as in a user's shell at the workspace root: none of the variables the README's commands
/// set, no flags or toolchain of the test run's (the workspace's rust-toolchain.toml and
/// .cargo/config.toml decide), building in `target_dir`.
fn users_shell<'a>(cmd: &'a mut Command, target_dir: &Path) -> &'a mut Command {
    cmd.current_dir(workspace_root())
        .env("CARGO_TARGET_DIR", target_dir);
    for var in ENV_VARS.iter().chain(&[
        "HOPLOC_PORT",
        "CARGO_TARGET_AVR_NONE_RUNNER",
        "RAVEDUDE_PORT",
        "RUSTFLAGS",
        "CARGO_ENCODED_RUSTFLAGS",
        "CARGO_BUILD_TARGET",
        "RUSTUP_TOOLCHAIN",
    ]) {
        cmd.env_remove(var);
    }
    cmd
}

/// The serial ports a block's commands name (`HOPLOC_PORT=/dev/…`), or the one port a user
/// with one board has if they name none.
fn ports_of(flashes: &[Flash]) -> Vec<String> {
    let mut ports: Vec<String> = flashes
        .iter()
        .filter_map(|f| f.vars.get("HOPLOC_PORT").cloned())
        .collect();
    ports.sort();
    ports.dedup();
    if ports.is_empty() {
        ports.push("/dev/ttyACM0".into());
    }
    ports
}

/// What is wrong with `call` as the flash `f` (empty: nothing), the block having had `ports`
/// in the stand-in /dev `dev`.
fn check_call(
    f: &Flash,
    call: &Call,
    ports: &[String],
    target_dir: &Path,
    dev: &Path,
) -> Vec<String> {
    let mut wrong = Vec::new();
    let name = crate_name(f.role);
    let elf = target_dir
        .join("avr-none")
        .join(f.profile)
        .join(format!("{name}.elf"));
    // Cargo hands the runner the ELF's path relative to where it runs when it can: the
    // arguments with that path made whole.
    let whole = |p: &str| call.cwd.join(p).display().to_string();
    let args: Vec<String> = call
        .args
        .iter()
        .map(|a| {
            match a
                .strip_prefix("flash:w:")
                .and_then(|a| a.strip_suffix(":e"))
            {
                Some(p) => format!("flash:w:{}:e", whole(p)),
                None if a.ends_with(".elf") => whole(a),
                None => a.clone(),
            }
        })
        .collect();
    match f.runner {
        Runner::FlashUno => {
            let port = match f.vars.get("HOPLOC_PORT") {
                Some(p) => p.clone(),
                None if ports.len() == 1 => ports[0].clone(),
                None => format!("(one of {ports:?}: flash-uno refuses to choose)"),
            };
            let port = match port.strip_prefix("/dev/") {
                Some(name) => dev.join(name).display().to_string(),
                None => port,
            };
            let want: Vec<String> = [
                "-c",
                "arduino",
                "-p",
                "m328p",
                "-b",
                "115200",
                "-P",
                &port,
                "-D",
                "-U",
                &format!("flash:w:{}:e", elf.display()),
            ]
            .map(String::from)
            .to_vec();
            if call.tool != "avrdude" || args != want {
                wrong.push(format!(
                    "{} called with {:?}, expected avrdude with {want:?}",
                    call.tool, call.args
                ));
            }
        }
        Runner::Ravedude => {
            let want = vec![elf.display().to_string()];
            if call.tool != "ravedude" || args != want {
                wrong.push(format!(
                    "{} called with {:?}, expected ravedude with {want:?}",
                    call.tool, call.args
                ));
            }
            // ravedude reads the board from the Ravedude.toml where it runs.
            if !call.cwd.join("Ravedude.toml").exists() {
                wrong.push(format!("ravedude ran in {:?}, no Ravedude.toml", call.cwd));
            }
        }
    }
    let Some(bytes) = &call.elf else {
        wrong.push("no ELF was handed over".into());
        return wrong;
    };
    let image = match simavr::elf::inspect_bytes(bytes) {
        Ok(i) => i,
        Err(e) => {
            wrong.push(format!("the ELF handed over: {e}"));
            return wrong;
        }
    };
    if hoploc::firmware::role_of(&image) != Some(f.role) {
        wrong.push(format!(
            "the ELF is not {name}: {:?}",
            hoploc::firmware::role_of(&image)
        ));
    }
    let built_in = image.eeprom.as_deref().map(Config::from_bytes);
    match (f.config(), built_in) {
        (Ok(want), Some(Ok(got))) if want == got => {}
        (Ok(want), got) => wrong.push(format!(
            "the ELF's built-in config (.eeprom) is {got:?}, the line's variables give {want:?}"
        )),
        (Err(e), _) => wrong.push(format!(
            "the line's variables are invalid ({e}), yet it built"
        )),
    }
    wrong
}

/// Runs `block` and checks each of its flashes; the error lists everything that went wrong.
fn run_and_check(block: &Block, flashes: &[Flash], target_dir: &Path) -> Result<(), String> {
    let ports = ports_of(flashes);
    let Run { calls, dev } = run_block(block, &ports, target_dir)?;
    let mut wrong = Vec::new();
    if calls.len() != flashes.len() {
        wrong.push(format!(
            "{} flashing commands, {} calls of avrdude/ravedude: {:?}",
            flashes.len(),
            calls.len(),
            calls.iter().map(|c| (&c.tool, &c.args)).collect::<Vec<_>>()
        ));
    }
    for (f, call) in flashes.iter().zip(&calls) {
        for w in check_call(f, call, &ports, target_dir, &dev) {
            wrong.push(format!("{:?}: {w}", f.text.trim()));
        }
    }
    if wrong.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "README.md line {} ({}):\n{}",
            block.line,
            block.heading,
            wrong.join("\n")
        ))
    }
}

/// The workspace's target directory (the one `hoploc_tests::firmware_elf` builds in).
fn target_dir() -> PathBuf {
    workspace_root().join("target")
}

#[test]
fn every_flashing_command_in_the_readme_works_as_typed() {
    let blocks = readme_flashing_blocks();
    // The places the README flashes boards: the four-Unos walkthrough's step 3, the flashing
    // section (flash-uno and ravedude), the node config's examples. A block this reading no
    // longer finds (another fence, a command it does not see as flashing) fails here.
    for (heading, at_least) in [
        ("From Unos with XBees to a testbed", 6),
        ("Building the firmware and flashing real boards", 4),
        ("Node config: at build time, or provisioned over USB", 2),
    ] {
        let n: usize = blocks
            .iter()
            .filter(|(b, _)| b.heading == heading)
            .map(|(_, f)| f.len())
            .sum();
        assert!(n >= at_least, "{heading}: {n} flashing commands found");
    }
    let roles: Vec<Role> = blocks
        .iter()
        .flat_map(|(_, f)| f.iter().map(|f| f.role))
        .collect();
    for role in Role::ALL {
        assert!(
            roles.contains(&role),
            "no README command flashes the {role:?}"
        );
    }
    assert!(
        blocks
            .iter()
            .any(|(_, f)| f.iter().any(|f| f.runner == Runner::Ravedude)),
        "no ravedude command found"
    );

    let target = target_dir();
    let mut failures = Vec::new();
    for (block, flashes) in &blocks {
        let start = std::time::Instant::now();
        match run_and_check(block, flashes, &target) {
            Ok(()) => eprintln!(
                "README.md line {} ({}): {} flashes as expected, {:.0?}",
                block.line,
                block.heading,
                flashes.len(),
                start.elapsed()
            ),
            Err(e) => failures.push(e),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The README's flashing block holding `what`, with its flashes.
fn readme_block(what: &str) -> (Block, Vec<Flash>) {
    readme_flashing_blocks()
        .into_iter()
        .find(|(b, _)| b.lines.iter().any(|l| l.contains(what)))
        .unwrap_or_else(|| panic!("no flashing block has {what:?}"))
}

/// The check fails when a README block, as typed, does not do what it says: here with a crate
/// that does not exist (cargo fails, `bash -e` stops), and with a `cd` into a directory that
/// does not exist (`bash -e` goes on after a failed `cd … &&`, so the flashes miscount).
#[test]
fn a_broken_flashing_command_fails_the_check() {
    let target = target_dir();
    let (mut block, flashes) = readme_block("cargo fw-run -p sink-fw");
    for l in &mut block.lines {
        *l = l.replace("-p sink-fw", "-p sink-firmware");
    }
    let err = run_and_check(&block, &flashes, &target).expect_err("a crate that does not exist");
    assert!(
        err.contains("the block failed") && err.contains("`sink-firmware` not found"),
        "{err}"
    );

    let (mut block, flashes) = readme_block("cd ../agent-fw");
    for l in &mut block.lines {
        *l = l.replace("cd ../agent-fw", "cd ../agnet-fw");
    }
    let err =
        run_and_check(&block, &flashes, &target).expect_err("a directory that does not exist");
    assert!(
        err.contains(&format!(
            "{} flashing commands, {} calls",
            flashes.len(),
            flashes.len() - 1
        )),
        "{err}"
    );
}

/// The reading of the README: `cd` carries over lines, variables belong to their line, a block
/// of host programs is no flashing block, and among flashes a command it does not know is an
/// error.
#[test]
fn the_readme_reading_follows_the_shell() {
    let block = |text: &str| Block {
        heading: String::new(),
        line: 1,
        lines: text.lines().map(String::from).collect(),
    };
    let f = flashes(&block(
        "cargo fw   # all\n\
         cd anchor-fw\n\
         HOPLOC_ID=2 cargo run   # anchor 2\n\
         cd ../sink-fw && HOPLOC_PORT=/dev/ttyACM1 cargo run\n\
         cd .. && cargo fw-run -p agent-fw",
    ))
    .unwrap();
    let vars = |pairs: &[(&str, &str)]| -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|&(k, v)| (k.to_string(), v.to_string()))
            .collect()
    };
    let got: Vec<_> = f.iter().map(|f| (f.role, f.profile, &f.vars)).collect();
    assert_eq!(
        got,
        [
            (Role::Anchor, "debug", &vars(&[("HOPLOC_ID", "2")])),
            (
                Role::Sink,
                "debug",
                &vars(&[("HOPLOC_PORT", "/dev/ttyACM1")])
            ),
            (Role::Agent, "fw", &vars(&[])),
        ]
    );
    assert_eq!(f[0].config().unwrap().id, 2);
    let host = "cargo run -p hoploc -- provision --port /dev/ttyACM0";
    assert!(
        flashes(&block(host)).unwrap().is_empty(),
        "no flash, not run"
    );
    let both = format!("cargo fw-run -p sink-fw\n{host}");
    assert!(
        flashes(&block(&both)).is_err(),
        "a host program among flashes"
    );
    assert!(flashes(&block("cargo run")).is_err(), "no crate to run");
    assert!(flashes(&block("cargo install ravedude\ncd anchor-fw && cargo run")).is_err());
    assert!(flashes(&block("cd anchor-fw\nexport HOPLOC_ID=2\ncargo run")).is_err());
}
