//! The live map (`--web`) end to end: its event stream read as a browser reads it (the format,
//! a client that joins late, the end of the run), `hoploc monitor --web` fed lines and stopped
//! by its input's end and by Ctrl-C, and the page in headless Chromium against the run it shows.
//!
//! The demo runs use the firmware ELFs of `cargo fw` (./test.sh builds them first) and a short
//! room10: the warm-up, then two stops of 3 s. The browser test needs Chromium (Debian's
//! `chromium`, which scripts/setup.sh installs; `HOPLOC_CHROMIUM` names another binary), started
//! headless and driven through the DevTools protocol on a pipe. With
//! `HOPLOC_DOCS_SCREENSHOT=1` it also writes its screenshot of the page to docs/live-map.png.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use loc_proto::msg::{ChannelList, Position, Report, MAX_MESSAGE};
use loc_proto::sink_line::{Estimator, RawReport, SinkLine};
use serde_json::{json, Value};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hoploc")
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A fresh directory under the test target's temporary directory.
fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("web-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// room10 cut short: its warm-up, then 3 s at (5, 5) and 3 s at (2, 7).
fn short_room10(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(workspace().join("scenarios/room10.toml")).unwrap();
    let start = text.find("path = [").expect("room10's path");
    let end = start + text[start..].find("\n]").expect("the path's end") + 2;
    let short = format!(
        "{}path = [\n  {{ position = [5.0, 5.0], dwell_s = 3.0 }},\n  \
         {{ position = [2.0, 7.0], dwell_s = 3.0 }},\n]{}",
        &text[..start],
        &text[end..]
    )
    .replace("name = \"room10\"", "name = \"room10-short\"");
    let p = dir.join("room10-short.toml");
    std::fs::write(&p, short).unwrap();
    p
}

/// A running hoploc command with the live map: its stdout, line by line as it comes, and the
/// page's address.
struct Run {
    child: Child,
    stdout: Arc<Mutex<String>>,
    reader: Option<std::thread::JoinHandle<()>>,
    /// `127.0.0.1:PORT`.
    addr: String,
}

impl Run {
    fn start(args: &[&str], stdin: Stdio) -> Run {
        let mut child = Command::new(bin())
            .args(args)
            .current_dir(workspace())
            .stdin(stdin)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("run hoploc");
        let (tx, rx) = mpsc::channel();
        let stdout = Arc::new(Mutex::new(String::new()));
        let (out, pipe) = (stdout.clone(), child.stdout.take().unwrap());
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines() {
                let Ok(line) = line else { return };
                if let Some(i) = line.find("live map: http://") {
                    let rest = &line[i + "live map: http://".len()..];
                    let _ = tx.send(rest[..rest.find('/').unwrap()].to_string());
                }
                let mut o = out.lock().unwrap();
                o.push_str(&line);
                o.push('\n');
            }
        });
        let addr = rx
            .recv_timeout(Duration::from_secs(120))
            .unwrap_or_else(|_| {
                let _ = child.kill();
                panic!("no live map address printed:\n{}", stdout.lock().unwrap())
            });
        Run {
            child,
            stdout,
            reader: Some(reader),
            addr,
        }
    }

    /// Waits for the command to end (at most `limit`); its exit status and stdout.
    fn wait(mut self, limit: Duration) -> (ExitStatus, String) {
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed() > limit {
                let _ = self.child.kill();
                panic!(
                    "hoploc still runs after {limit:?}:\n{}",
                    self.stdout.lock().unwrap()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        self.reader.take().unwrap().join().unwrap();
        let out = self.stdout.lock().unwrap().clone();
        (status, out)
    }
}

impl Drop for Run {
    fn drop(&mut self) {
        if self.reader.is_some() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// One server-sent event.
#[derive(Clone, Debug, PartialEq)]
struct Sse {
    id: usize,
    event: String,
    data: Value,
}

/// Reads `/events` from `addr` as a browser would, to its end; `seen` is called with each event
/// as it arrives. Checks the response's headers and each event's form.
fn read_events(addr: &str, mut seen: impl FnMut(&Sse)) -> Vec<Sse> {
    let mut s = TcpStream::connect(addr).expect("connect to the live map");
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    write!(
        s,
        "GET /events HTTP/1.1\r\nHost: {addr}\r\nAccept: text/event-stream\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut raw = Vec::new();
    let mut buf = [0u8; 8192];
    let more = |s: &mut TcpStream, raw: &mut Vec<u8>, buf: &mut [u8]| -> bool {
        match s.read(buf) {
            Ok(0) => false,
            Ok(n) => {
                raw.extend_from_slice(&buf[..n]);
                true
            }
            Err(e) => panic!("reading the event stream: {e}"),
        }
    };
    let head_end = loop {
        if let Some(i) = raw.windows(4).position(|w| w == b"\r\n\r\n") {
            break i + 4;
        }
        assert!(more(&mut s, &mut raw, &mut buf), "no response head");
    };
    let head = String::from_utf8_lossy(&raw[..head_end]).to_lowercase();
    assert!(head.starts_with("http/1.1 200"), "{head}");
    assert!(head.contains("content-type: text/event-stream"), "{head}");
    assert!(head.contains("cache-control: no-cache"), "{head}");
    assert!(head.contains("transfer-encoding: chunked"), "{head}");
    let mut body = raw.split_off(head_end);
    // The chunked body, decoded as it comes; the text cut into events at each blank line.
    let (mut text, mut events) = (String::new(), Vec::new());
    'chunks: loop {
        let size_end = loop {
            if let Some(i) = body.windows(2).position(|w| w == b"\r\n") {
                break i;
            }
            assert!(
                more(&mut s, &mut body, &mut buf),
                "the stream ended mid-chunk"
            );
        };
        let size = usize::from_str_radix(std::str::from_utf8(&body[..size_end]).unwrap(), 16)
            .expect("a chunk size");
        if size == 0 {
            break 'chunks;
        }
        while body.len() < size_end + 2 + size + 2 {
            assert!(
                more(&mut s, &mut body, &mut buf),
                "the stream ended mid-chunk"
            );
        }
        text.push_str(std::str::from_utf8(&body[size_end + 2..size_end + 2 + size]).unwrap());
        body.drain(..size_end + 2 + size + 2);
        while let Some(i) = text.find("\n\n") {
            let block: String = text.drain(..i + 2).collect();
            let mut fields = block
                .trim_end()
                .lines()
                .map(|l| l.split_once(": ").unwrap());
            let (id, event, data) = (
                fields.next().unwrap(),
                fields.next().unwrap(),
                fields.next().unwrap(),
            );
            assert!(fields.next().is_none(), "{block}");
            assert_eq!((id.0, event.0, data.0), ("id", "event", "data"), "{block}");
            let e = Sse {
                id: id.1.parse().unwrap(),
                event: event.1.to_string(),
                data: serde_json::from_str(data.1).unwrap(),
            };
            assert_eq!(e.data["type"], e.event, "{block}");
            seen(&e);
            events.push(e);
        }
    }
    assert!(text.is_empty(), "{text}");
    events
}

/// The stream's events of one kind.
fn of<'a>(events: &'a [Sse], kind: &str) -> Vec<&'a Value> {
    events
        .iter()
        .filter(|e| e.event == kind)
        .map(|e| &e.data)
        .collect()
}

/// fixes.csv: per row, (estimator, seq, time, x, y, settled).
fn csv_fixes(dir: &Path) -> Vec<(String, u64, f64, f64, f64, bool)> {
    let text = std::fs::read_to_string(dir.join("fixes.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (
                c[5].to_string(),
                c[1].parse().unwrap(),
                c[0].parse().unwrap(),
                c[6].parse().unwrap(),
                c[7].parse().unwrap(),
                c[12] == "true",
            )
        })
        .collect()
}

/// The server has stopped: nothing listens on `addr`.
fn assert_stopped(addr: &str) {
    assert!(
        TcpStream::connect(addr).is_err(),
        "the live map still listens on {addr} after the run"
    );
}

#[test]
fn the_event_stream_gives_a_late_client_the_history_and_ends_with_the_run() {
    let dir = tmp("stream");
    let scenario = short_room10(&dir);
    let out_dir = dir.join("out");
    let run = Run::start(
        &[
            "demo",
            scenario.to_str().unwrap(),
            "--sink",
            "host",
            "--web",
            "--speed",
            "4",
            "--out-dir",
            out_dir.to_str().unwrap(),
        ],
        Stdio::null(),
    );
    assert!(run.addr.starts_with("127.0.0.1:"), "{}", run.addr);
    let t0 = Instant::now();
    // Client A from the start, noting when each fix arrives; client B once A has 20 fixes.
    let a_fixes = Arc::new(AtomicUsize::new(0));
    let a = {
        let (addr, n) = (run.addr.clone(), a_fixes.clone());
        std::thread::spawn(move || {
            let mut arrivals = Vec::new();
            let events = read_events(&addr, |e| {
                if e.event == "fix" {
                    n.fetch_add(1, Ordering::SeqCst);
                    arrivals.push(t0.elapsed());
                }
            });
            (events, arrivals)
        })
    };
    while a_fixes.load(Ordering::SeqCst) < 20 {
        assert!(t0.elapsed() < Duration::from_secs(60), "no fixes streamed");
        std::thread::sleep(Duration::from_millis(10));
    }
    let joined_after = a_fixes.load(Ordering::SeqCst);
    let b = read_events(&run.addr, |_| {});
    let (a, arrivals) = a.join().unwrap();
    let addr = run.addr.clone();
    let (status, stdout) = run.wait(Duration::from_secs(120));
    assert_stopped(&addr);
    assert!(status.success(), "{stdout}");
    assert!(stdout.contains("live map: http://127.0.0.1:"), "{stdout}");
    assert!(stdout.contains("paced: at most 4× real time"), "{stdout}");

    // The format: ids 0, 1, 2…; setup first, end last, once each.
    assert!(a.iter().enumerate().all(|(i, e)| e.id == i));
    assert_eq!(a[0].event, "setup");
    assert_eq!(a.last().unwrap().event, "end");
    assert_eq!(of(&a, "setup").len(), 1);
    assert_eq!(of(&a, "end").len(), 1);
    // The late client got the same events: the history, then the rest.
    assert!(joined_after >= 20 && b.len() > joined_after);
    assert_eq!(a, b);
    // A's fixes came as the run went, not all at its end (at 4× real time the six seconds of
    // stops take 1.5 s).
    let (first, last) = (arrivals[0], *arrivals.last().unwrap());
    assert!(
        last - first > Duration::from_millis(700),
        "{first:?}…{last:?}"
    );

    let setup = &a[0].data;
    assert_eq!(setup["source"], "demo");
    assert_eq!(setup["clock"], "simulated");
    assert_eq!(setup["area"], json!([10.0, 10.0]));
    assert_eq!(
        setup["anchors"],
        json!([
            {"id": 1, "x": 0.0, "y": 0.0}, {"id": 2, "x": 10.0, "y": 0.0},
            {"id": 3, "x": 10.0, "y": 10.0}, {"id": 4, "x": 0.0, "y": 10.0}
        ])
    );
    assert_eq!(setup["path"], json!([[5.0, 5.0], [2.0, 7.0]]));
    assert_eq!(
        setup["estimators"],
        json!(["MLE", "MMSE", "MLE-fixed", "MLE-P0only"])
    );
    let end = &a.last().unwrap().data;
    assert_eq!(end["reason"], "the scenario's end");
    assert_eq!(end["t"], 14.0);

    // One data path: the stream's fixes are fixes.csv's rows, in its order.
    let fixes = of(&a, "fix");
    let csv = csv_fixes(&out_dir);
    assert_eq!(fixes.len(), csv.len());
    assert_eq!(end["fixes"], csv.len());
    assert!(csv.len() >= 4 * 50, "{} fixes", csv.len());
    for (f, (est, seq, t, x, y, settled)) in fixes.iter().zip(&csv) {
        assert_eq!(f["est"], est.as_str(), "{f}");
        assert_eq!(f["seq"], *seq, "{f}");
        assert!((f["t"].as_f64().unwrap() - t).abs() < 1e-4, "{f}");
        assert_eq!(
            (f["x"].as_f64(), f["y"].as_f64()),
            (Some(*x), Some(*y)),
            "{f}"
        );
        assert_eq!(f["settled"], *settled, "{f}");
        assert_eq!(f["anchors"], 4, "{f}");
    }
    let truths: Vec<&Value> = fixes.iter().map(|f| &f["truth"]).collect();
    assert_eq!(truths[0], &json!([5.0, 5.0]));
    assert_eq!(*truths.last().unwrap(), &json!([2.0, 7.0]));
    // The anchors as the reports heard them, and the host sink's counters.
    let anchors = of(&a, "anchors");
    let heard = &anchors.last().unwrap()["anchors"];
    assert_eq!(heard.as_array().unwrap().len(), 4, "{heard}");
    for (i, xy) in [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
        .into_iter()
        .enumerate()
    {
        let an = &heard[i];
        assert_eq!(
            (an["id"].as_u64(), an["x"].as_f64(), an["y"].as_f64()),
            (Some(i as u64 + 1), Some(xy.0), Some(xy.1))
        );
        assert_eq!(an["heard"], true, "{an}");
    }
    let status = of(&a, "status");
    let last = status.last().expect("the host sink's counters");
    assert_eq!(last["missing"], 0);
    assert!(
        last["reports"].as_u64().unwrap() as usize * 4 >= csv.len(),
        "{last}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ctrl_c_ends_a_demo_with_its_table() {
    let dir = tmp("demo-ctrl-c");
    let scenario = short_room10(&dir);
    let out_dir = dir.join("out");
    let run = Run::start(
        &[
            "demo",
            scenario.to_str().unwrap(),
            "--sink",
            "host",
            "--web",
            "--speed",
            "3",
            "--out-dir",
            out_dir.to_str().unwrap(),
        ],
        Stdio::null(),
    );
    let n = Arc::new(AtomicUsize::new(0));
    let client = {
        let (addr, n) = (run.addr.clone(), n.clone());
        std::thread::spawn(move || {
            read_events(&addr, |e| {
                n.fetch_add(usize::from(e.event == "fix"), Ordering::SeqCst);
            })
        })
    };
    let t0 = Instant::now();
    while n.load(Ordering::SeqCst) < 8 {
        assert!(t0.elapsed() < Duration::from_secs(60), "no fixes streamed");
        std::thread::sleep(Duration::from_millis(10));
    }
    let kill = Command::new("kill")
        .args(["-INT", &run.child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let events = client.join().unwrap();
    let addr = run.addr.clone();
    let (status, stdout) = run.wait(Duration::from_secs(60));
    assert!(status.success(), "{stdout}");
    assert_stopped(&addr);
    let end = &events.last().unwrap().data;
    assert_eq!(end["reason"], "Ctrl-C");
    let t = end["t"].as_f64().unwrap();
    assert!(t < 14.0, "{end}");
    // The table of what ran, and the page's fixes are its CSV's.
    assert!(
        stdout.contains(&format!("Ctrl-C: stopped at {t:.1} s of 14 s simulated")),
        "{stdout}"
    );
    assert!(stdout.contains("RMSE and bias per position"), "{stdout}");
    assert!(
        stdout.contains(&format!("emulation: {t:.1} s simulated")),
        "{stdout}"
    );
    assert_eq!(of(&events, "fix").len(), csv_fixes(&out_dir).len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Sink lines of report `seq`: its `report` line (anchors 1…3 heard, 4 only when `four`), then
/// its MLE and MMSE `fix` lines.
fn sink_lines(seq: u16, four: bool) -> String {
    let mut r = Report::new(1, seq, 4, ChannelList::new(&[1, 12]).unwrap());
    for (i, (x, y)) in [(0, 0), (1000, 0), (1000, 1000), (0, 1000)]
        .into_iter()
        .enumerate()
    {
        r.positions[i] = Position { x, y };
        if i < 3 || four {
            r.rssi[0][i] = 60 + i as u8;
            r.rssi[1][i] = 62 + i as u8;
        }
    }
    let mut msg = [0u8; MAX_MESSAGE];
    let n = r.encode(&mut msg).unwrap();
    let mut s = String::new();
    let Ok(()) = RawReport::write(&msg[..n], &mut s);
    for (estimator, dx) in [(Estimator::Mle, 0), (Estimator::Mmse, 20)] {
        let Ok(()) = SinkLine::Fix {
            agent: 1,
            seq,
            estimator,
            x: 300 + 10 * seq as i16 + dx,
            y: 400,
            alpha_x100: 290,
            p0_x100: -4100,
            anchors: 4,
            flags: 1,
        }
        .write(&mut s);
    }
    s
}

fn status_line() -> String {
    let mut s = String::new();
    let Ok(()) = SinkLine::Status {
        uptime_s: 10,
        frames: 12,
        reports: 8,
        drops: 1,
        checksum_errors: 2,
        foreign: 3,
        fixes: 8,
        repeats: 0,
        failed: 4,
    }
    .write(&mut s);
    s
}

/// `hoploc monitor --web` reading `lines` from stdin, a client on its stream; `stop` ends the
/// session (closes stdin, or sends SIGINT). Returns the events, the exit status and stdout.
fn monitor_session(
    stop: impl FnOnce(&mut Option<ChildStdin>, u32),
) -> (Vec<Sse>, ExitStatus, String) {
    let mut run = Run::start(
        &["monitor", "--web", "--truth", "3,4", "--area", "10x10"],
        Stdio::piped(),
    );
    let mut stdin = run.child.stdin.take();
    let n = Arc::new(AtomicUsize::new(0));
    let client = {
        let (addr, n) = (run.addr.clone(), n.clone());
        std::thread::spawn(move || {
            read_events(&addr, |_| {
                n.fetch_add(1, Ordering::SeqCst);
            })
        })
    };
    let wait_for = |k: usize| {
        let t0 = Instant::now();
        while n.load(Ordering::SeqCst) < k {
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "{} events",
                n.load(Ordering::SeqCst)
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    };
    wait_for(1);
    let mut text: String = (0..8).map(|seq| sink_lines(seq, seq < 2)).collect();
    text += &status_line();
    stdin.as_mut().unwrap().write_all(text.as_bytes()).unwrap();
    stdin.as_mut().unwrap().flush().unwrap();
    // setup, 16 fixes, the anchors (all heard, then 4 greyed), the status.
    wait_for(20);
    stop(&mut stdin, run.child.id());
    let events = client.join().unwrap();
    let addr = run.addr.clone();
    let (status, stdout) = run.wait(Duration::from_secs(30));
    assert_stopped(&addr);
    (events, status, stdout)
}

fn check_monitor_events(events: &[Sse]) {
    assert_eq!(events[0].event, "setup");
    let setup = &events[0].data;
    assert_eq!(
        (
            &setup["source"],
            &setup["clock"],
            &setup["area"],
            &setup["path"]
        ),
        (
            &json!("monitor"),
            &json!("wall"),
            &json!([10.0, 10.0]),
            &json!([[3.0, 4.0]])
        )
    );
    let fixes = of(events, "fix");
    assert_eq!(fixes.len(), 16);
    for (k, f) in fixes.iter().enumerate() {
        let seq = k / 2;
        let (est, dx) = if k % 2 == 0 {
            ("MLE", 0.0)
        } else {
            ("MMSE", 0.2)
        };
        assert_eq!(f["est"], est);
        assert_eq!(f["seq"], seq);
        assert!(
            (f["x"].as_f64().unwrap() - (3.0 + 0.1 * seq as f64 + dx)).abs() < 1e-9,
            "{f}"
        );
        assert_eq!(
            (&f["y"], &f["alpha"], &f["p0"]),
            (&json!(4.0), &json!(2.9), &json!(-41.0))
        );
        assert_eq!(f["truth"], json!([3.0, 4.0]));
    }
    // Anchor 4 was heard by the first two reports only: greyed at the fifth without it, the
    // seventh, and nothing changed after.
    let anchors = of(events, "anchors");
    let first = &anchors[0]["anchors"];
    let last = &anchors.last().unwrap()["anchors"];
    assert_eq!(first[3]["heard"], true, "{first}");
    assert_eq!(
        (&last[3]["heard"], &last[3]["x"], &last[3]["y"]),
        (&json!(false), &json!(0.0), &json!(10.0))
    );
    assert!((0..3).all(|i| last[i]["heard"] == true), "{last}");
    assert_eq!(anchors.last().unwrap()["reports"], 7);
    let status = of(events, "status");
    assert_eq!(status.len(), 1);
    let st = status[0];
    assert_eq!(
        [
            &st["frames"],
            &st["missing"],
            &st["corrupt"],
            &st["foreign"],
            &st["failed"],
            &st["damaged"]
        ],
        [
            &json!(12),
            &json!(1),
            &json!(2),
            &json!(3),
            &json!(4),
            &json!(0)
        ]
    );
}

#[test]
fn monitor_streams_what_it_reads_and_stops_at_the_end_of_its_input() {
    let (events, status, stdout) = monitor_session(|stdin, _| drop(stdin.take()));
    assert!(status.success(), "{stdout}");
    check_monitor_events(&events);
    let end = &events.last().unwrap().data;
    assert_eq!(
        (&end["reason"], &end["fixes"]),
        (&json!("the end of the input"), &json!(16))
    );
    assert!(stdout.contains("16 fix lines"), "{stdout}");
}

#[test]
fn ctrl_c_ends_monitor_web_as_its_input_would() {
    let (events, status, stdout) = monitor_session(|_, pid| {
        let kill = Command::new("kill")
            .args(["-INT", &pid.to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
    });
    assert!(status.success(), "{status:?}: {stdout}");
    check_monitor_events(&events);
    let end = &events.last().unwrap().data;
    assert_eq!(
        (&end["reason"], &end["fixes"]),
        (&json!("Ctrl-C"), &json!(16))
    );
    // The summary as at the end of the input.
    assert!(stdout.contains("Ctrl-C: stopped"), "{stdout}");
    assert!(
        stdout.contains("16 fix lines") && stdout.contains("RMSE"),
        "{stdout}"
    );
}

#[test]
fn replay_serves_its_whole_log_until_ctrl_c() {
    let dir = tmp("replay");
    let log = dir.join("sink.log");
    let mut text = String::from("# truth 3 4\n");
    text.extend((0..8).map(|seq| sink_lines(seq, seq < 2)));
    text += &status_line();
    std::fs::write(&log, text).unwrap();
    let run = Run::start(
        &["replay", log.to_str().unwrap(), "--web", "--area", "10x10"],
        Stdio::null(),
    );
    // The log is replayed at once: every client gets all of it, then the end, however late.
    let first = read_events(&run.addr, |_| {});
    std::thread::sleep(Duration::from_millis(300));
    let again = read_events(&run.addr, |_| {});
    assert_eq!(first, again);
    let setup = &first[0].data;
    assert_eq!(
        (&setup["source"], &setup["clock"]),
        (&json!("replay"), &json!("log"))
    );
    let end = &first.last().unwrap().data;
    assert_eq!(
        (&end["reason"], &end["t"]),
        (&json!("the end of the log"), &json!(8.0))
    );
    // Its fixes: the sink's lines, and every host algorithm's per report, each at its report.
    let fixes = of(&first, "fix");
    let count = |est: &str| fixes.iter().filter(|f| f["est"] == est).count();
    assert_eq!(
        (count("sink MLE"), count("sink MMSE"), count("MLE")),
        (8, 8, 8)
    );
    assert_eq!(end["fixes"], fixes.len());
    assert!(fixes.iter().all(|f| f["truth"] == json!([3.0, 4.0])));
    let sink: Vec<f64> = fixes
        .iter()
        .filter(|f| f["est"] == "sink MLE")
        .map(|f| f["t"].as_f64().unwrap())
        .collect();
    assert_eq!(sink, (1..=8).map(f64::from).collect::<Vec<_>>());
    assert_eq!(of(&first, "status").len(), 1);
    let addr = run.addr.clone();
    let kill = Command::new("kill")
        .args(["-INT", &run.child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let (status, stdout) = run.wait(Duration::from_secs(30));
    assert!(status.success(), "{stdout}");
    assert!(
        stdout.contains("8 reports (0 unreadable), 16 sink fix lines"),
        "{stdout}"
    );
    // The table counts the same fixes.
    for est in ["MLE", "sink MLE"] {
        let row = stdout
            .lines()
            .find(|l| {
                l.starts_with("(3.00, 4.00)")
                    && l[13..].trim_start().starts_with(&format!("{est} "))
            })
            .unwrap_or_else(|| panic!("no {est} row:\n{stdout}"));
        assert!(row.split_whitespace().any(|w| w == "8"), "{row}");
    }
    assert_stopped(&addr);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_live_map_binds_only_what_it_is_told() {
    // A port that is taken is an error with the address, not a panic.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let out = Command::new(bin())
        .args(["monitor", "--web", "--web-port", &port])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!("cannot listen on 127.0.0.1:{port}")),
        "{err}"
    );
    // --web-port and --web-bind need --web; --web-bind needs an address.
    for args in [
        &["monitor", "--web-port", "8080"][..],
        &["monitor", "--web-bind", "0.0.0.0"],
        &["monitor", "--web", "--web-bind", "localhost"],
        &["monitor", "--web", "--web-port", "65536"],
        &["demo", "--boot", "--web"],
    ] {
        let out = Command::new(bin()).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
    }
    // The address given is the one it listens on (another loopback address: the banner's
    // warning for addresses beyond this machine is a unit test of hoploc::web).
    let run = Run::start(
        &["monitor", "--web", "--web-bind", "127.0.0.2"],
        Stdio::null(),
    );
    assert!(run.addr.starts_with("127.0.0.2:"), "{}", run.addr);
    let (status, stdout) = run.wait(Duration::from_secs(30));
    assert!(status.success(), "{stdout}");
    assert!(!stdout.contains("beyond this machine"), "{stdout}");
}

// ------------------------------------------------------------------------------------------
// The page in a real browser.

/// Headless Chromium driven through the DevTools protocol on a pipe (`--remote-debugging-pipe`:
/// JSON messages ended by a NUL byte, read from its fd 3, written to its fd 4).
struct Chromium {
    child: Child,
    to: ChildStdin,
    from: mpsc::Receiver<Value>,
    next: u64,
    session: Option<String>,
}

impl Chromium {
    fn launch(profile: &Path) -> Chromium {
        let exe = std::env::var("HOPLOC_CHROMIUM").unwrap_or_else(|_| "chromium".into());
        // The shell hands our pipes to Chromium as fds 3 and 4.
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(r#"exec "$0" "$@" 3<&0 4>&1 0</dev/null 1>&2"#)
            .arg(&exe)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-extensions",
                "--hide-scrollbars",
                "--remote-debugging-pipe",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg("about:blank")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("start {exe}: {e}"));
        let (to, mut pipe) = (child.stdin.take().unwrap(), child.stdout.take().unwrap());
        let (tx, from) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let mut chunk = [0u8; 65536];
            while let Ok(n) = pipe.read(&mut chunk) {
                if n == 0 {
                    return;
                }
                buf.extend_from_slice(&chunk[..n]);
                while let Some(i) = buf.iter().position(|&b| b == 0) {
                    let msg: Vec<u8> = buf.drain(..=i).collect();
                    if let Ok(v) = serde_json::from_slice(&msg[..i]) {
                        if tx.send(v).is_err() {
                            return;
                        }
                    }
                }
            }
        });
        let mut c = Chromium {
            child,
            to,
            from,
            next: 0,
            session: None,
        };
        let version = c.call("Browser.getVersion", json!({}));
        assert!(
            version["product"].as_str().is_some(),
            "{exe} answers no DevTools call: is Debian's chromium installed (scripts/setup.sh)?"
        );
        c
    }

    /// Calls `method`, on the page once one is attached; its result.
    fn call(&mut self, method: &str, params: Value) -> Value {
        self.next += 1;
        let mut msg = json!({"id": self.next, "method": method, "params": params});
        if let Some(s) = &self.session {
            msg["sessionId"] = json!(s);
        }
        let mut bytes = serde_json::to_vec(&msg).unwrap();
        bytes.push(0);
        self.to
            .write_all(&bytes)
            .and_then(|()| self.to.flush())
            .unwrap();
        loop {
            let v = self
                .from
                .recv_timeout(Duration::from_secs(30))
                .unwrap_or_else(|_| panic!("Chromium did not answer {method}"));
            if v["id"] == self.next {
                assert!(v.get("error").is_none(), "{method}: {v}");
                return v["result"].clone();
            }
        }
    }

    /// Opens `url` in a new page of `size` CSS pixels and attaches to it.
    fn open(&mut self, url: &str, size: (u32, u32)) {
        let target = self.call("Target.createTarget", json!({"url": url}))["targetId"].clone();
        let attached = self.call(
            "Target.attachToTarget",
            json!({"targetId": target, "flatten": true}),
        );
        self.session = Some(attached["sessionId"].as_str().unwrap().to_string());
        self.call(
            "Emulation.setDeviceMetricsOverride",
            json!({"width": size.0, "height": size.1, "deviceScaleFactor": 1, "mobile": false}),
        );
    }

    /// The value of JavaScript `expr` in the page.
    fn eval(&mut self, expr: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expr, "returnByValue": true}),
        );
        r["result"]["value"].clone()
    }

    /// A PNG of the page.
    fn screenshot(&mut self) -> Vec<u8> {
        let r = self.call("Page.captureScreenshot", json!({"format": "png"}));
        base64(r["data"].as_str().unwrap())
    }
}

impl Drop for Chromium {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Standard base64 (with padding) decoded.
fn base64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    for quad in s.as_bytes().chunks(4) {
        let n = quad.iter().take_while(|&&c| c != b'=').count();
        let v = quad[..n]
            .iter()
            .fold(0u32, |v, &c| v << 6 | u32::from(val(c)))
            << (6 * (4 - n));
        out.extend_from_slice(&v.to_be_bytes()[1..n]);
    }
    out
}

/// What the page shows, read off its DOM.
const READ_PAGE: &str = r##"JSON.stringify({
  anchors: [...document.querySelectorAll("#map .anchor")].map((g) =>
    ({ id: +g.dataset.id, x: +g.dataset.x, y: +g.dataset.y, heard: g.dataset.heard === "true" })),
  trails: Object.fromEntries([...document.querySelectorAll("#map .trail")].map((g) =>
    [g.dataset.est, [...g.querySelectorAll("circle.fix")].map((c) => [+c.dataset.x, +c.dataset.y])])),
  rows: Object.fromEntries([...document.querySelectorAll("#ests tr[data-est]")].map((r) =>
    [r.dataset.est, { n: +r.dataset.n, x: +r.dataset.x, y: +r.dataset.y,
      rmse: r.dataset.rmse ? +r.dataset.rmse : null }])),
  fixes: +document.getElementById("summary").dataset.fixes,
  state: document.getElementById("state").textContent,
  counters: Object.fromEntries([...document.querySelectorAll("#status tr[data-counter]")].map((r) =>
    [r.dataset.counter, +r.cells[1].textContent])),
  truth: ((m) => (m ? [+m.dataset.x, +m.dataset.y] : null))(document.getElementById("truthmark")),
  path: document.querySelectorAll("#map polyline.path").length,
})"##;

#[test]
fn the_page_in_chromium_shows_the_run() {
    let t0 = Instant::now();
    let dir = tmp("browser");
    let scenario = short_room10(&dir);
    let out_dir = dir.join("out");
    // The browser first, so the page opens as soon as the address is printed.
    let mut chromium = Chromium::launch(&dir.join("profile"));
    let run = Run::start(
        &[
            "demo",
            scenario.to_str().unwrap(),
            "--web",
            "--speed",
            "0",
            "--out-dir",
            out_dir.to_str().unwrap(),
        ],
        Stdio::null(),
    );
    chromium.open(&format!("http://{}/", run.addr), (1360, 900));
    // Wait for the end of the run, noting whether the page showed fixes while it went on.
    let mut live_fixes = 0u64;
    loop {
        let v = chromium.eval(
            r#"(s => s ? s.dataset.state + " " + s.dataset.fixes : "")(document.getElementById("summary"))"#,
        );
        let v = v.as_str().unwrap_or("").to_string();
        if let Some(n) = v.strip_prefix("live ") {
            live_fixes = live_fixes.max(n.parse().unwrap());
        }
        if v.starts_with("ended") {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(90),
            "the page did not see the end: {v}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let (status, stdout) = run.wait(Duration::from_secs(60));
    assert!(status.success(), "{stdout}");
    assert!(
        live_fixes > 0,
        "the page showed no fix while the run went on"
    );
    let page: Value = serde_json::from_str(chromium.eval(READ_PAGE).as_str().unwrap()).unwrap();

    assert!(
        page["state"]
            .as_str()
            .unwrap()
            .starts_with("ended: the scenario's end"),
        "{page}"
    );
    // The anchors at their positions, heard.
    assert_eq!(
        page["anchors"],
        json!([
            {"id": 1, "x": 0, "y": 0, "heard": true}, {"id": 2, "x": 10, "y": 0, "heard": true},
            {"id": 3, "x": 10, "y": 10, "heard": true}, {"id": 4, "x": 0, "y": 10, "heard": true}
        ])
    );
    // Per estimator: the fixes counted and drawn are the CSV's, the last drawn is its last row.
    let csv = csv_fixes(&out_dir);
    assert_eq!(page["fixes"], csv.len());
    for est in ["MLE", "MMSE", "MLE-fixed", "MLE-P0only"] {
        let rows: Vec<[f64; 2]> = csv
            .iter()
            .filter(|r| r.0 == est)
            .map(|r| [r.3, r.4])
            .collect();
        let row = &page["rows"][est];
        assert_eq!(row["n"], rows.len(), "{est}: {row}");
        let last = rows.last().unwrap();
        assert_eq!(
            (row["x"].as_f64(), row["y"].as_f64()),
            (Some(last[0]), Some(last[1])),
            "{est}"
        );
        // The trail: the last 50 fixes, in order.
        let drawn: Vec<[f64; 2]> = serde_json::from_value(page["trails"][est].clone()).unwrap();
        assert_eq!(drawn, rows[rows.len().saturating_sub(50)..], "{est}");
        // The running RMSE is the table's over every stop.
        let table_row = stdout
            .lines()
            .find(|l| l.starts_with("all ") && l.split_whitespace().nth(1) == Some(est))
            .unwrap_or_else(|| panic!("no `all {est}` row:\n{stdout}"));
        let rmse: f64 = table_row
            .split_whitespace()
            .nth(3)
            .unwrap()
            .parse()
            .unwrap();
        let page_rmse = row["rmse"].as_f64().unwrap();
        assert!(
            (page_rmse - rmse).abs() <= 5e-4,
            "{est}: page {page_rmse}, table {rmse}"
        );
    }
    assert_eq!(page["truth"], json!([2, 7]));
    assert_eq!(page["path"], 1);
    // The sink firmware's counters: its last status line's.
    let line = stdout
        .lines()
        .find(|l| l.starts_with("sink firmware's last status line"))
        .unwrap_or_else(|| panic!("no status line:\n{stdout}"));
    // "… (at 10 s): 49 frames, …"
    let frames: u64 = line
        .split("): ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    assert!(frames > 0, "{line}");
    assert_eq!(page["counters"]["frames"], frames, "{page}");

    // The controls: an estimator hidden and shown again, the view paused and resumed.
    let drawn = |c: &mut Chromium| {
        c.eval(r#"+document.querySelector('#map .trail[data-est="MMSE"]').dataset.drawn"#)
    };
    chromium.eval(r#"document.querySelector('input[data-toggle="MMSE"]').click()"#);
    assert_eq!(drawn(&mut chromium), json!(0));
    chromium.eval(r#"document.querySelector('input[data-toggle="MMSE"]').click()"#);
    assert_eq!(drawn(&mut chromium), json!(50));
    chromium.eval(r#"document.getElementById("pause").click()"#);
    assert_eq!(
        chromium.eval(r#"document.getElementById("state").textContent"#),
        json!("paused")
    );
    chromium.eval(r#"document.getElementById("pause").click()"#);
    assert_eq!(
        chromium.eval(r#"document.getElementById("pause").textContent"#),
        json!("Pause")
    );

    let png = chromium.screenshot();
    assert_eq!(&png[1..4], b"PNG");
    std::fs::write(dir.join("live-map.png"), &png).unwrap();
    if std::env::var_os("HOPLOC_DOCS_SCREENSHOT").is_some() {
        std::fs::write(workspace().join("docs/live-map.png"), &png).unwrap();
    }
    eprintln!("the browser test took {:.1} s", t0.elapsed().as_secs_f64());
}
