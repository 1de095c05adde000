//! `--web`: the live map of `hoploc demo`, `hoploc monitor` and `hoploc replay` in a browser.
//!
//! [`Web::start`] serves one page ([`PAGE`], built into the binary: no file, no CDN, no fetch
//! beyond this server) and an event stream, `/events`, in the server-sent events format: each
//! event is
//!
//! ```text
//! id: 17
//! event: fix
//! data: {"type":"fix","t":9.312,"seq":5,"est":"MLE","x":4.93,…}
//! ```
//!
//! with `id` its index in the run (0, 1, 2…), `event` its kind and `data` one line of JSON whose
//! `type` is the kind again ([`Event`] documents the fields). A browser that connects gets every
//! event of the run so far at once, then each new one as the run publishes it; one that
//! reconnects with `Last-Event-ID` gets those after it. The run's last event is `end`, after
//! which the stream closes and the server stops (a client that does not read is given two
//! seconds); `hoploc replay`, whose run is over at once, serves its log until Ctrl-C.
//!
//! One data path: the commands publish the records their terminal tables and plots are made
//! of — `hoploc demo` each [`crate::fixes::FixRow`] as it writes its CSV row, `hoploc monitor`
//! each fix line as it tallies it — so the page cannot show another fix than the table counts.
//! The page computes its running RMSE from those fixes, over the fixes the table counts
//! (`settled`).
//!
//! The server is axum (HTTP/1 only, no extractors) on a current-thread tokio runtime in a
//! thread of its own, beside the run's loop, which never waits for it: publishing an event is a
//! lock, a push and a wake-up. It binds 127.0.0.1 unless `--web-bind` says otherwise; the page
//! and its stream have no password and no encryption, so anyone who can reach another address
//! sees the run.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use axum::body::Body;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use loc_proto::msg::Report;
use loc_proto::sink_line::SinkLine;
use serde::Serialize;
use tokio::sync::watch;

use crate::fixes::{name, FixRow};
use crate::health::{Health, HealthEvent};

/// The page: HTML, CSS and script in one file, built into the binary.
pub const PAGE: &str = include_str!("web/page.html");

/// How long the server waits, after the run's end, for clients to take the rest of the stream.
const DRAIN: Duration = Duration::from_secs(2);

/// Reports an anchor may go unheard before the page greys it (about a second at room10's rate).
pub const HEARD_REPORTS: usize = 5;

/// The `--web` options of a command.
#[derive(Clone, Debug, clap::Args)]
pub struct WebArgs {
    /// Serve a live map of the run on this machine and print its address: the room, the
    /// anchors, each estimator's fixes with a fading trail, the truth, and a panel of numbers
    /// (fixes/s, errors, α and P0, the sink's counters, the anchors' health), pushed as the fixes
    /// come. Everything the page needs is built into hoploc: it works with no network.
    #[arg(long)]
    pub web: bool,
    /// The live map's port [default: a free one, printed].
    #[arg(long, requires = "web", value_name = "PORT")]
    pub web_port: Option<u16>,
    /// The address the live map listens on. Only this machine can reach 127.0.0.1; another
    /// address (0.0.0.0: every network the machine is on) lets anyone who reaches it watch the
    /// run: the page has no password and no encryption.
    #[arg(long, requires = "web", value_name = "ADDR", default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub web_bind: IpAddr,
}

/// Where the run's positions come from, as the page names it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Setup {
    /// The command: `demo`, `monitor` or `replay`.
    pub source: &'static str,
    /// A title for the page.
    pub title: String,
    /// What runs, in a sentence.
    pub about: String,
    /// What `t` counts: `simulated` seconds (the demo), `wall` seconds since the start
    /// (monitor), or the `log`'s report count (replay).
    pub clock: &'static str,
    /// The room, metres (`[width, height]`), when known; else the page frames what it has seen.
    pub area: Option<[f64; 2]>,
    /// The anchors known before any report (the demo's scenario), id and position in metres.
    pub anchors: Vec<AnchorPos>,
    /// The agent's true path, metres (the demo's stops; monitor's `--truth`), when known.
    pub path: Vec<[f64; 2]>,
    /// The estimators whose fixes may come, in table order.
    pub estimators: Vec<&'static str>,
    /// The fixes per second the network's schedule allows, when known.
    pub rate: Option<f64>,
}

/// An anchor's id and position.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct AnchorPos {
    /// 1…8.
    pub id: u8,
    /// Metres.
    pub x: f64,
    /// Metres.
    pub y: f64,
}

/// One fix: a [`FixRow`] of the demo, a fix line of the monitor.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Fix {
    /// Time, s (see [`Setup::clock`]).
    pub t: f64,
    /// The report's sequence number.
    pub seq: u16,
    /// The estimator's name ([`crate::fixes::name`]; `MLE`, `MMSE` for the sink's).
    pub est: &'static str,
    /// The fix, metres.
    pub x: f64,
    /// The fix, metres.
    pub y: f64,
    /// α the estimate used.
    pub alpha: f64,
    /// P0 the estimate used, dBm.
    pub p0: f64,
    /// Anchors used.
    pub anchors: u8,
    /// The agent's true position then, metres, when known.
    pub truth: Option<[f64; 2]>,
    /// Whether the table counts it (the demo leaves out the warm-up and each move).
    pub settled: bool,
}

impl From<&FixRow> for Fix {
    fn from(r: &FixRow) -> Fix {
        Fix {
            t: r.time_s,
            seq: r.seq,
            est: name(r.estimator),
            x: r.pos[0],
            y: r.pos[1],
            alpha: r.alpha,
            p0: r.p0,
            anchors: r.anchors,
            truth: Some(r.truth),
            settled: r.settled,
        }
    }
}

/// The anchors as the sink hears them, sent when that changes.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Anchors {
    /// Time, s.
    pub t: f64,
    /// Reports seen so far.
    pub reports: usize,
    /// Every anchor a report gave a position for, in id order.
    pub anchors: Vec<AnchorState>,
    /// The anchor health check's verdict in words.
    pub health: String,
}

/// One anchor in [`Anchors`].
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AnchorState {
    /// 1…8.
    pub id: u8,
    /// Its configured position, metres (as the reports carry it).
    pub x: f64,
    /// Metres.
    pub y: f64,
    /// Whether one of the last [`HEARD_REPORTS`] reports heard it (its beacon's RSSI, or a
    /// relay row from it).
    pub heard: bool,
    /// The last report that heard it, by its time.
    pub last_heard_t: Option<f64>,
    /// Its RSSI at the agent in the last report that heard it, dBm (the channels' mean).
    pub rssi_dbm: Option<f64>,
    /// The health check's flag: where its links place it, how far that is, the score.
    pub flagged: Option<Flagged>,
}

/// A flagged anchor's figures ([`crate::health::Flag`]).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Flagged {
    /// Where its links place it, metres.
    pub x: f64,
    /// Metres.
    pub y: f64,
    /// Distance from its configured position, metres.
    pub offset_m: f64,
    /// The check's score.
    pub score: f64,
}

/// The sink's counters: its `status` line's, or the host sink's.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Status {
    /// Time, s.
    pub t: f64,
    /// Frames received.
    pub frames: u32,
    /// Reports decoded.
    pub reports: u32,
    /// Reports missing from the agents' sequences.
    pub missing: u32,
    /// Frames that failed to decode (checksum).
    pub corrupt: u32,
    /// Frames that are not hoploc messages.
    pub foreign: u32,
    /// Estimates made.
    pub fixes: u32,
    /// Reports the sink had already.
    pub repeats: u32,
    /// Reports the agents' radios could not deliver.
    pub failed: u32,
    /// Sink lines the host found damaged (monitor), when it reads lines.
    pub damaged: Option<usize>,
}

impl Status {
    /// The counters of a `status` line at `t` (`None` for another line).
    pub fn of_line(t: f64, l: &SinkLine) -> Option<Status> {
        let [_, frames, reports, drops, corrupt, foreign, fixes, repeats, failed] =
            l.status_fields()?;
        Some(Status {
            t,
            frames,
            reports,
            missing: drops,
            corrupt,
            foreign,
            fixes,
            repeats,
            failed,
            damaged: None,
        })
    }

    /// The host sink's counters at `t`.
    pub fn of_counters(t: f64, c: &sink_fw::Counters) -> Status {
        Status {
            t,
            frames: c.frames(),
            reports: c.reports(),
            missing: c.drops(),
            corrupt: c.checksum_errors(),
            foreign: c.foreign(),
            fixes: c.fixes(),
            repeats: c.repeats(),
            failed: c.failed(),
            damaged: None,
        }
    }

    /// The same counters, whatever the time.
    fn same(&self, o: &Status) -> bool {
        Status {
            t: o.t,
            ..self.clone()
        } == *o
    }
}

/// The run's end.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct End {
    /// Time, s.
    pub t: f64,
    /// Why: the scenario's end, the end of the input, Ctrl-C…
    pub reason: String,
    /// Fix events published.
    pub fixes: usize,
}

/// An event of the stream.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    /// The first: what the run is.
    Setup(Setup),
    /// A fix.
    Fix(Fix),
    /// The anchors as heard, when that changes.
    Anchors(Anchors),
    /// The sink's counters, when they change.
    Status(Status),
    /// The last.
    End(End),
}

impl Event {
    /// Its kind: the SSE `event` field and the JSON `type`.
    pub fn kind(&self) -> &'static str {
        match self {
            Event::Setup(_) => "setup",
            Event::Fix(_) => "fix",
            Event::Anchors(_) => "anchors",
            Event::Status(_) => "status",
            Event::End(_) => "end",
        }
    }

    /// The event as the stream sends it, with id `id`.
    pub fn frame(&self, id: usize) -> String {
        // Serialising these plain structs cannot fail; NaN and infinities become null.
        let data = serde_json::to_string(self).unwrap_or_else(|_| "{}".into());
        format!("id: {id}\nevent: {}\ndata: {data}\n\n", self.kind())
    }
}

/// The events so far, and whether the run ended.
#[derive(Debug, Default)]
struct Log {
    frames: Vec<String>,
    fixes: usize,
    ended: bool,
}

/// What the run and the server share.
#[derive(Debug)]
struct Hub {
    log: Mutex<Log>,
    /// Bumped at each event and at the end: wakes the streams.
    wake: watch::Sender<usize>,
    /// Ctrl-C was pressed.
    interrupted: AtomicBool,
    /// The server is to stop.
    stop: AtomicBool,
}

impl Hub {
    fn new() -> Hub {
        Hub {
            log: Mutex::new(Log::default()),
            wake: watch::Sender::new(0),
            interrupted: AtomicBool::new(false),
            stop: AtomicBool::new(false),
        }
    }

    /// The log (a thread that panicked while holding it left it whole: every change is a push
    /// or a flag).
    fn log(&self) -> MutexGuard<'_, Log> {
        self.log.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn publish(&self, e: &Event) {
        let n = {
            let mut log = self.log();
            if log.ended {
                return;
            }
            let id = log.frames.len();
            log.frames.push(e.frame(id));
            log.fixes += usize::from(matches!(e, Event::Fix(_)));
            log.ended = matches!(e, Event::End(_));
            log.frames.len()
        };
        self.wake.send_replace(n);
    }

    /// Every event from index `next` on, as one chunk (empty when there is none), the index
    /// after them, and whether the run ended.
    fn since(&self, next: usize) -> (String, usize, bool) {
        let log = self.log();
        let next = next.min(log.frames.len());
        (log.frames[next..].concat(), log.frames.len(), log.ended)
    }

    /// Tells the server to stop.
    fn stop(&self) {
        self.stop.store(true, Ordering::SeqCst);
        self.wake.send_modify(|_| {});
    }

    async fn stopping(&self) {
        let mut rx = self.wake.subscribe();
        while !self.stop.load(Ordering::SeqCst) {
            if rx.changed().await.is_err() {
                return;
            }
        }
    }
}

/// The live map's server, running beside a command. Dropping it ends the run's stream ("stopped")
/// and stops the server.
#[derive(Debug)]
pub struct Web {
    hub: Arc<Hub>,
    addr: SocketAddr,
    thread: Option<JoinHandle<()>>,
}

impl Web {
    /// Binds `args`' address and port and serves the page and the stream from a thread of its
    /// own. With `catch_ctrl_c`, Ctrl-C no longer ends the process: [`Web::interrupted`] turns
    /// true and the command ends its run (a second Ctrl-C ends the process, exit code 130).
    pub fn start(args: &WebArgs, catch_ctrl_c: bool) -> Result<Web, String> {
        let want = SocketAddr::new(args.web_bind, args.web_port.unwrap_or(0));
        let listener = std::net::TcpListener::bind(want)
            .and_then(|l| l.set_nonblocking(true).map(|()| l))
            .map_err(|e| format!("--web: cannot listen on {want}: {e}"))?;
        let addr = listener.local_addr().map_err(|e| format!("--web: {e}"))?;
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .enable_time()
            .build()
            .map_err(|e| format!("--web: {e}"))?;
        let listener = {
            let _in = rt.enter();
            tokio::net::TcpListener::from_std(listener).map_err(|e| format!("--web: {e}"))?
        };
        let hub = Arc::new(Hub::new());
        let app = Router::new()
            .route("/", get(page))
            .route("/events", get(events))
            .fallback(not_found)
            .with_state(hub.clone());
        let h = hub.clone();
        let thread = std::thread::Builder::new()
            .name("hoploc-web".into())
            .spawn(move || {
                rt.block_on(async move {
                    if catch_ctrl_c {
                        let h = h.clone();
                        tokio::spawn(async move {
                            while tokio::signal::ctrl_c().await.is_ok() {
                                if h.interrupted.swap(true, Ordering::SeqCst) {
                                    std::process::exit(130);
                                }
                            }
                        });
                    }
                    let end = h.clone();
                    let serve = axum::serve(listener, app)
                        .with_graceful_shutdown(async move { end.stopping().await });
                    let server = tokio::spawn(std::future::IntoFuture::into_future(serve));
                    h.stopping().await;
                    let _ = tokio::time::timeout(DRAIN, server).await;
                });
            })
            .map_err(|e| format!("--web: {e}"))?;
        Ok(Web {
            hub,
            addr,
            thread: Some(thread),
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's address, `http://ADDR:PORT/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// The line a command prints about the page, which it serves `until` (words).
    pub fn banner(&self, until: &str) -> String {
        banner(self.addr, until)
    }

    /// Sends `e` to every browser, now and later.
    pub fn send(&self, e: &Event) {
        self.hub.publish(e);
    }

    /// Sends a fix.
    pub fn fix(&self, f: Fix) {
        self.send(&Event::Fix(f));
    }

    /// Whether Ctrl-C was pressed (with `catch_ctrl_c`).
    pub fn interrupted(&self) -> bool {
        self.hub.interrupted.load(Ordering::SeqCst)
    }

    /// Fix events sent so far.
    pub fn fixes(&self) -> usize {
        self.hub.log().fixes
    }

    /// Ends the stream with `reason` at `t` and stops the server once the browsers have the
    /// rest (at most two seconds later).
    pub fn finish(mut self, t: f64, reason: &str) {
        self.end(t, reason);
        self.stop();
    }

    /// Ends the stream with `reason` at `t`, then serves the run as it stands (every browser
    /// that connects gets all of it) until Ctrl-C (with `catch_ctrl_c`), and stops.
    pub fn serve_until_interrupted(mut self, t: f64, reason: &str) {
        self.end(t, reason);
        while !self.interrupted() {
            std::thread::sleep(Duration::from_millis(50));
        }
        self.stop();
    }

    fn end(&self, t: f64, reason: &str) {
        self.hub.publish(&Event::End(End {
            t,
            reason: reason.to_string(),
            fixes: self.fixes(),
        }));
    }

    fn stop(&mut self) {
        self.hub.stop();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Web {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.end(f64::NAN, "stopped");
            self.stop();
        }
    }
}

/// The line a command prints about a page served on `addr` `until` (words).
pub fn banner(addr: SocketAddr, until: &str) -> String {
    let mut s = format!("live map: http://{addr}/ (served {until})");
    if !addr.ip().is_loopback() {
        s += "; listening beyond this machine: anyone who reaches this address can watch";
    }
    s
}

async fn page() -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        PAGE,
    )
        .into_response()
}

async fn not_found() -> Response {
    (StatusCode::NOT_FOUND, "not found: the live map is at /\n").into_response()
}

async fn events(
    axum::extract::State(hub): axum::extract::State<Arc<Hub>>,
    headers: HeaderMap,
) -> Response {
    // A reconnecting EventSource names the last event it has.
    let from = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<usize>().ok())
        .map_or(0, |id| id.saturating_add(1));
    let rx = hub.wake.subscribe();
    let stream = futures_util::stream::unfold((hub, from, rx), |(hub, next, mut rx)| async move {
        loop {
            let (chunk, n, ended) = hub.since(next);
            if !chunk.is_empty() {
                return Some((Ok::<_, Infallible>(chunk), (hub, n, rx)));
            }
            if ended || rx.changed().await.is_err() {
                return None;
            }
        }
    });
    (
        [
            (header::CONTENT_TYPE, "text/event-stream"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        Body::from_stream(stream),
    )
        .into_response()
}

/// The anchors as the sink hears them, from its reports: which ones the last
/// [`HEARD_REPORTS`] reports heard, where the reports place them, and the health check's flags
/// (its events come from the command's own check, [`crate::health::Health`]).
#[derive(Clone, Debug, Default)]
pub struct AnchorWatch {
    reports: usize,
    /// Per anchor id: position, index of the last report that heard it, its time and RSSI.
    anchors: BTreeMap<u8, Heard>,
    flags: BTreeMap<u8, Flagged>,
    sent: Option<Vec<AnchorState>>,
    health: String,
}

#[derive(Clone, Copy, Debug)]
struct Heard {
    pos: [f64; 2],
    report: usize,
    t: f64,
    rssi_dbm: Option<f64>,
}

impl AnchorWatch {
    /// A watch with no report yet.
    pub fn new() -> AnchorWatch {
        AnchorWatch::default()
    }

    /// Report `r` at `t`, with what the health check made of it (`events`, what its
    /// [`Health::on_report`] returned for `r`, and `check` after it); the [`Event::Anchors`] to
    /// send when something the page shows changed.
    pub fn on_report(
        &mut self,
        t: f64,
        r: &Report,
        events: &[HealthEvent],
        check: &Health,
    ) -> Option<Event> {
        self.reports += 1;
        let n = (r.anchors as usize).min(loc_core::MAX_ANCHORS);
        let c = r.channels.len().min(loc_core::MAX_CHANNELS);
        for i in 0..n {
            let rssi: Vec<f64> = (0..c)
                .map(|ch| r.rssi[ch][i])
                .filter(|&b| b != 0)
                .map(|b| -f64::from(b))
                .collect();
            let relayed =
                r.has_relay && (0..c).any(|ch| r.relay[ch][i][..n].iter().any(|&b| b != 0));
            if rssi.is_empty() && !relayed {
                continue;
            }
            let p = r.positions[i];
            self.anchors.insert(
                i as u8 + 1,
                Heard {
                    pos: [f64::from(p.x) / 100.0, f64::from(p.y) / 100.0],
                    report: self.reports,
                    t,
                    rssi_dbm: (!rssi.is_empty())
                        .then(|| rssi.iter().sum::<f64>() / rssi.len() as f64),
                },
            );
        }
        for e in events {
            match e {
                HealthEvent::Flagged(f) => {
                    self.flags.insert(
                        f.id,
                        Flagged {
                            x: f.test.estimate.x,
                            y: f.test.estimate.y,
                            offset_m: f.test.offset_m,
                            score: f.test.score,
                        },
                    );
                }
                HealthEvent::Cleared { id } => {
                    self.flags.remove(id);
                }
            }
        }
        let health = if !self.flags.is_empty() {
            let ids: Vec<String> = self.flags.keys().map(|k| k.to_string()).collect();
            format!(
                "anchor {} flagged: its links contradict its position",
                ids.join(", ")
            )
        } else if check.judged() {
            "no anchor flagged: every anchor's links agree with its position".into()
        } else {
            format!(
                "no verdict yet (it takes {} reports with anchor-to-anchor RSSI, and 4 anchors)",
                check.config().min_reports
            )
        };
        let now: Vec<AnchorState> = self
            .anchors
            .iter()
            .map(|(&id, h)| AnchorState {
                id,
                x: h.pos[0],
                y: h.pos[1],
                heard: self.reports - h.report < HEARD_REPORTS,
                last_heard_t: Some(h.t),
                rssi_dbm: h.rssi_dbm,
                flagged: self.flags.get(&id).copied(),
            })
            .collect();
        // Sent when what is heard, where, or flagged changes; not for each report's times.
        let key = |v: &[AnchorState]| -> Vec<(u8, [u64; 2], bool, bool)> {
            v.iter()
                .map(|a| {
                    (
                        a.id,
                        [a.x.to_bits(), a.y.to_bits()],
                        a.heard,
                        a.flagged.is_some(),
                    )
                })
                .collect()
        };
        if self.sent.as_deref().map(key) == Some(key(&now)) && health == self.health {
            return None;
        }
        self.health = health;
        self.sent = Some(now.clone());
        Some(Event::Anchors(Anchors {
            t,
            reports: self.reports,
            anchors: now,
            health: self.health.clone(),
        }))
    }
}

/// What a command that reads sink lines (`monitor`, `replay`) keeps for the live map: the events
/// not yet taken, and the anchors and counters last sent.
#[derive(Clone, Debug, Default)]
pub struct Feed {
    events: Vec<Event>,
    anchors: AnchorWatch,
    status: StatusWatch,
}

impl Feed {
    /// A fix, as it goes into the command's table.
    pub fn fix(&mut self, fix: Fix) {
        self.events.push(Event::Fix(fix));
    }

    /// A status line's counters, sent when they changed.
    pub fn status(&mut self, s: Option<Status>) {
        self.events.extend(s.and_then(|s| self.status.on(s)));
    }

    /// Report `r` at `t` and what the health check made of it ([`AnchorWatch::on_report`]).
    pub fn report(&mut self, t: f64, r: &Report, events: &[HealthEvent], check: &Health) {
        self.events
            .extend(self.anchors.on_report(t, r, events, check));
    }

    /// The events since the last call.
    pub fn take(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }
}

/// The sink's counters, sent when they change.
#[derive(Clone, Debug, Default)]
pub struct StatusWatch {
    last: Option<Status>,
}

impl StatusWatch {
    /// `s`, when its counters differ from the last sent.
    pub fn on(&mut self, s: Status) -> Option<Event> {
        if self.last.as_ref().is_some_and(|l| l.same(&s)) {
            return None;
        }
        self.last = Some(s.clone());
        Some(Event::Status(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_is_small_and_fetches_nothing_from_elsewhere() {
        assert!(PAGE.len() < 40 * 1024, "{} bytes", PAGE.len());
        for far in ["http://", "https://", "//cdn", "@import", "src=\"/"] {
            assert!(!PAGE.contains(far), "the page names {far}");
        }
        assert!(PAGE.contains("new EventSource(\"events\")"));
    }

    #[test]
    fn the_banner_warns_when_the_page_reaches_beyond_this_machine() {
        let local = banner("127.0.0.1:8080".parse().unwrap(), "until the run ends");
        assert_eq!(
            local,
            "live map: http://127.0.0.1:8080/ (served until the run ends)"
        );
        assert!(!banner("[::1]:80".parse().unwrap(), "").contains("beyond"));
        for far in ["0.0.0.0:8080", "[::]:8080", "192.0.2.7:8080"] {
            let b = banner(far.parse().unwrap(), "until the run ends");
            assert!(
                b.contains("anyone who reaches this address can watch"),
                "{b}"
            );
        }
    }

    #[test]
    fn a_frame_is_an_sse_event_of_one_json_line() {
        let e = Event::End(End {
            t: 1.5,
            reason: "a\nb".into(),
            fixes: 3,
        });
        let f = e.frame(7);
        assert_eq!(
            f,
            "id: 7\nevent: end\ndata: {\"type\":\"end\",\"t\":1.5,\"reason\":\"a\\nb\",\"fixes\":3}\n\n"
        );
        let nan = Event::End(End {
            t: f64::NAN,
            reason: String::new(),
            fixes: 0,
        });
        assert!(nan.frame(0).contains("\"t\":null"));
    }

    #[test]
    fn a_late_client_gets_the_history_and_the_end_closes_the_log() {
        let hub = Hub::new();
        let fix = |t| {
            Event::Fix(Fix {
                t,
                seq: 1,
                est: "MLE",
                x: 1.0,
                y: 2.0,
                alpha: 3.0,
                p0: -40.0,
                anchors: 4,
                truth: None,
                settled: true,
            })
        };
        hub.publish(&fix(1.0));
        hub.publish(&fix(2.0));
        let (all, n, ended) = hub.since(0);
        assert_eq!((n, ended), (2, false));
        assert!(all.starts_with("id: 0\nevent: fix\n") && all.contains("id: 1\n"));
        assert_eq!(hub.since(1).0, fix(2.0).frame(1));
        assert_eq!(hub.since(9).0, "");
        hub.publish(&Event::End(End {
            t: 2.0,
            reason: "done".into(),
            fixes: 2,
        }));
        hub.publish(&fix(3.0));
        let (rest, n, ended) = hub.since(2);
        assert_eq!((n, ended), (3, true));
        assert!(rest.starts_with("id: 2\nevent: end\n"), "{rest}");
        assert_eq!(*hub.wake.borrow(), 3);
    }

    #[test]
    fn anchors_grey_when_unheard_and_carry_the_health_flags() {
        use loc_proto::msg::{ChannelList, Position};
        let mut r = Report::new(1, 0, 4, ChannelList::new(&[1, 12]).unwrap());
        for i in 0..4 {
            r.positions[i] = Position {
                x: 1000 * (i as i16 % 2),
                y: 1000 * (i as i16 / 2),
            };
            r.rssi[0][i] = 60;
            r.rssi[1][i] = 70;
        }
        let mut w = AnchorWatch::new();
        let check = Health::default();
        let Some(Event::Anchors(a)) = w.on_report(0.2, &r, &[], &check) else {
            panic!("the first report's anchors");
        };
        assert_eq!(a.anchors.len(), 4);
        assert_eq!((a.anchors[1].x, a.anchors[1].y), (10.0, 0.0));
        assert!(a
            .anchors
            .iter()
            .all(|a| a.heard && a.rssi_dbm == Some(-65.0)));
        // Nothing changed: nothing sent.
        assert!(a.health.starts_with("no verdict yet"), "{}", a.health);
        assert_eq!(w.on_report(0.4, &r, &[], &check), None);
        // Anchor 3 goes quiet: greyed after HEARD_REPORTS reports without it.
        r.rssi[0][2] = 0;
        r.rssi[1][2] = 0;
        let mut greyed = None;
        for k in 0..HEARD_REPORTS {
            if let Some(Event::Anchors(a)) = w.on_report(1.0 + k as f64, &r, &[], &check) {
                greyed = Some((k, a));
            }
        }
        let (k, a) = greyed.expect("anchor 3 greyed");
        assert_eq!(k, HEARD_REPORTS - 1);
        assert!(!a.anchors[2].heard && a.anchors[2].last_heard_t == Some(0.4));
        assert!(a.anchors[0].heard);
        let flag = crate::health::Flag {
            id: 2,
            configured: loc_core::Point::new(10.0, 0.0),
            test: crate::health::AnchorTest {
                estimate: loc_core::Point::new(7.0, 1.0),
                offset_m: 3.2,
                residual_db: 4.0,
                score: 40.0,
            },
        };
        let flagged = [HealthEvent::Flagged(flag)];
        let Some(Event::Anchors(a)) = w.on_report(9.0, &r, &flagged, &check) else {
            panic!("a flag is sent");
        };
        assert_eq!(a.anchors[1].flagged.map(|f| f.offset_m), Some(3.2));
        assert!(a.health.starts_with("anchor 2 flagged"), "{}", a.health);
        let cleared = [HealthEvent::Cleared { id: 2 }];
        let Some(Event::Anchors(a)) = w.on_report(9.2, &r, &cleared, &check) else {
            panic!("a cleared flag is sent");
        };
        assert!(a.anchors[1].flagged.is_none());
    }

    #[test]
    fn status_is_sent_when_a_counter_changes() {
        let mut w = StatusWatch::default();
        let line = SinkLine::Status {
            uptime_s: 10,
            frames: 5,
            reports: 4,
            drops: 1,
            checksum_errors: 0,
            foreign: 2,
            fixes: 4,
            repeats: 0,
            failed: 0,
        };
        let s = Status::of_line(10.0, &line).unwrap();
        assert_eq!((s.missing, s.foreign), (1, 2));
        assert!(w.on(s.clone()).is_some());
        assert!(w
            .on(Status {
                t: 11.0,
                ..s.clone()
            })
            .is_none());
        assert!(w.on(Status { frames: 6, ..s }).is_some());
    }
}
