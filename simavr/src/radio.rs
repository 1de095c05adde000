//! A scripted stand-in for the XBee on an [`Avr`]'s UART0, for tests.
//!
//! The radio decodes the API frames the firmware writes (with [`xbee_api::Decoder`]), keeps the
//! bytes outside frames as text lines (the firmware prints text on the same line), and follows a
//! script of steps, in order:
//!
//! * [`ScriptedRadio::expect`]: the next frame the firmware writes must match, and must be
//!   complete (last byte through the UART) within `within_ms` of the step's start;
//! * [`ScriptedRadio::reply`] / [`ScriptedRadio::reply_frame`] / [`ScriptedRadio::reply_raw`]:
//!   answer `after_ms` after the end of the frame the previous `expect` matched (script start if
//!   none), encoded in the radio's API mode and delivered at the UART's byte rate; an `expect`
//!   with no reply after it is a radio that never answers;
//! * [`ScriptedRadio::send_at`] / [`ScriptedRadio::send_raw_at`]: send unsolicited at an
//!   absolute time (waits until then; frames the firmware writes meanwhile stay queued for the
//!   next `expect`);
//! * [`ScriptedRadio::expect_silence`]: no frame may start within `ms` of the step's start.
//!
//! A step starts when the one before it completes: at the end of the matched frame for
//! `expect`, at the answer's start for a reply or send, at the end of the quiet time for
//! silence. Frames after the last step are only collected. Every frame, text line and decode
//! error is kept with its cycle so tests can assert exact frames and times.

use std::fmt;

use xbee_api::{encode_raw, DecodeError, Decoder, Frame, Mode, ParseError, MAX_ENCODED};

use crate::avr::{cycles_to_ms, ms_to_cycles, Avr, State};

/// A frame the firmware wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeenFrame {
    /// Cycle of the start delimiter.
    pub cycle: u64,
    /// Cycle its last byte was through the UART (write of the last byte + one byte time).
    pub end_cycle: u64,
    /// Frame data (type byte first), unescaped, without length and checksum.
    pub data: Vec<u8>,
}

impl SeenFrame {
    /// Start time in ms.
    pub fn ms(&self) -> f64 {
        cycles_to_ms(self.cycle)
    }

    /// End time in ms.
    pub fn end_ms(&self) -> f64 {
        cycles_to_ms(self.end_cycle)
    }

    /// The frame type byte.
    pub fn frame_type(&self) -> u8 {
        self.data.first().copied().unwrap_or(0)
    }

    /// Parses the frame data.
    pub fn parse(&self) -> Result<Frame<'_>, ParseError> {
        Frame::parse(&self.data)
    }
}

impl fmt::Display for SeenFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "frame [{}]", hex(&self.data))?;
        if let Ok(p) = self.parse() {
            write!(f, " = {p:?}")?;
        }
        write!(f, " at {:.3}..{:.3} ms", self.ms(), self.end_ms())
    }
}

/// A text line the firmware printed outside frames (without the line ending).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextLine {
    /// Cycle of its first byte.
    pub cycle: u64,
    /// The text (lossy UTF-8).
    pub text: String,
}

impl TextLine {
    /// Time in ms.
    pub fn ms(&self) -> f64 {
        cycles_to_ms(self.cycle)
    }
}

/// A pause in the firmware's output this long ends a text line.
pub const LINE_GAP_MS: f64 = 100.0;

/// Splits the firmware's bytes outside API frames into [`TextLine`]s. A line ends at `\r`, `\n`
/// or `\r\n`, or at a pause of [`LINE_GAP_MS`] (command mode's `+++` is framed by silence, not
/// by a line end). Shared by [`ScriptedRadio`] and the modelled XBee.
#[derive(Debug, Default)]
pub(crate) struct LineSplitter {
    buf: Vec<u8>,
    /// Cycle of the first byte of `buf`.
    start: u64,
    /// Cycle of the last byte seen.
    last: u64,
    /// The last byte ended a line with `\r` (so a `\n` right after it is part of that end).
    after_cr: bool,
    lines: Vec<TextLine>,
}

impl LineSplitter {
    fn flush(&mut self) {
        if !self.buf.is_empty() {
            let t = std::mem::take(&mut self.buf);
            self.lines.push(TextLine {
                cycle: self.start,
                text: String::from_utf8_lossy(&t).into_owned(),
            });
        }
    }

    /// One byte of firmware output at `cycle`; `text` is false for bytes of an API frame.
    pub(crate) fn push(&mut self, cycle: u64, byte: u8, text: bool) {
        if cycle.saturating_sub(self.last) >= ms_to_cycles(LINE_GAP_MS) {
            self.flush();
        }
        self.last = cycle;
        if !text {
            return;
        }
        let after_cr = std::mem::take(&mut self.after_cr);
        match byte {
            b'\r' => {
                self.after_cr = true;
                self.flush();
            }
            b'\n' if after_cr => {}
            b'\n' => self.flush(),
            _ => {
                if self.buf.is_empty() {
                    self.start = cycle;
                }
                self.buf.push(byte);
            }
        }
    }

    /// The complete lines so far.
    pub(crate) fn lines(&self) -> &[TextLine] {
        &self.lines
    }
}

/// What an [`ScriptedRadio::expect`] step accepts.
pub enum Match {
    /// Exactly this frame data (type byte first).
    Data(Vec<u8>),
    /// A predicate, with a description for failure messages.
    Pred {
        /// What the predicate accepts, in words.
        desc: String,
        /// The predicate.
        f: Box<dyn Fn(&SeenFrame) -> bool + Send>,
    },
}

impl Match {
    /// Exactly this frame data (type byte first).
    pub fn data(frame_data: &[u8]) -> Match {
        Match::Data(frame_data.to_vec())
    }

    /// Exactly this frame.
    pub fn frame(frame: &Frame<'_>) -> Match {
        Match::Data(frame_data(frame))
    }

    /// Any frame of this type.
    pub fn frame_type(t: u8) -> Match {
        Match::pred(format!("any frame of type {t:#04x}"), move |f| {
            f.frame_type() == t
        })
    }

    /// Any frame accepted by `f`, described by `desc`.
    pub fn pred(desc: impl Into<String>, f: impl Fn(&SeenFrame) -> bool + Send + 'static) -> Match {
        Match::Pred {
            desc: desc.into(),
            f: Box::new(f),
        }
    }

    fn matches(&self, frame: &SeenFrame) -> bool {
        match self {
            Match::Data(d) => *d == frame.data,
            Match::Pred { f, .. } => f(frame),
        }
    }
}

impl fmt::Display for Match {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Match::Data(d) => {
                write!(f, "frame [{}]", hex(d))?;
                if let Ok(p) = Frame::parse(d) {
                    write!(f, " = {p:?}")?;
                }
                Ok(())
            }
            Match::Pred { desc, .. } => f.write_str(desc),
        }
    }
}

impl fmt::Debug for Match {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

#[derive(Debug)]
enum Step {
    Expect {
        m: Match,
        within: u64,
    },
    Reply {
        bytes: Vec<u8>,
        after: u64,
        what: String,
    },
    SendAt {
        at: u64,
        bytes: Vec<u8>,
        what: String,
    },
    Silence {
        dur: u64,
    },
}

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Step::Expect { m, within } => write!(f, "expect {m} within {} ms", ms(*within)),
            Step::Reply { after, what, .. } => write!(f, "reply {what} after {} ms", ms(*after)),
            Step::SendAt { at, what, .. } => write!(f, "send {what} at {} ms", ms(*at)),
            Step::Silence { dur } => write!(f, "expect no frame for {} ms", ms(*dur)),
        }
    }
}

/// The script was violated (or the firmware stopped, or the script did not finish in time).
#[derive(Clone, Debug, PartialEq)]
pub struct ScriptError {
    /// Index of the step (0-based).
    pub step: usize,
    /// The step, in words.
    pub expected: String,
    /// What happened instead.
    pub got: String,
    /// Simulated time of the failure in ms.
    pub at_ms: f64,
    /// The last text lines the firmware printed, for context.
    pub recent_lines: Vec<String>,
}

impl fmt::Display for ScriptError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "radio script step {} violated at {:.3} ms\n  expected: {}\n  got:      {}",
            self.step, self.at_ms, self.expected, self.got
        )?;
        if !self.recent_lines.is_empty() {
            write!(f, "\n  last firmware lines:")?;
            for l in &self.recent_lines {
                write!(f, "\n    {l}")?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for ScriptError {}

/// A scripted radio on an [`Avr`]'s UART0. See the module docs.
#[derive(Debug)]
pub struct ScriptedRadio {
    mode: Mode,
    decoder: Decoder,
    steps: Vec<Step>,
    cursor: usize,
    /// Start cycle of the current step.
    anchor: u64,
    /// End of the frame the last `expect` matched.
    last_match: u64,
    started: bool,
    /// How many UART output bytes were consumed.
    consumed: usize,
    frame_start: u64,
    frames: Vec<SeenFrame>,
    /// Index in `frames` of the next frame the script has not consumed.
    next_frame: usize,
    lines: LineSplitter,
    errors: Vec<(u64, DecodeError)>,
    sent: Vec<(u64, Vec<u8>)>,
    failed: Option<ScriptError>,
}

impl ScriptedRadio {
    /// An empty script for a radio in API `mode` (the testbed uses [`Mode::Escaped`]).
    pub fn new(mode: Mode) -> Self {
        ScriptedRadio {
            mode,
            decoder: Decoder::new(mode),
            steps: Vec::new(),
            cursor: 0,
            anchor: 0,
            last_match: 0,
            started: false,
            consumed: 0,
            frame_start: 0,
            frames: Vec::new(),
            next_frame: 0,
            lines: LineSplitter::default(),
            errors: Vec::new(),
            sent: Vec::new(),
            failed: None,
        }
    }

    /// Adds: the next frame must match `m` and end within `within_ms` of the step's start.
    pub fn expect(mut self, m: Match, within_ms: f64) -> Self {
        self.steps.push(Step::Expect {
            m,
            within: ms_to_cycles(within_ms),
        });
        self
    }

    /// Adds: answer with frame data `frame_data` (type byte first), `after_ms` after the end of
    /// the last matched frame.
    pub fn reply(mut self, frame_data: &[u8], after_ms: f64) -> Self {
        let bytes = self.encode(frame_data);
        self.steps.push(Step::Reply {
            bytes,
            after: ms_to_cycles(after_ms),
            what: format!("frame [{}]", hex(frame_data)),
        });
        self
    }

    /// Adds: answer with `frame`, `after_ms` after the end of the last matched frame.
    pub fn reply_frame(self, frame: &Frame<'_>, after_ms: f64) -> Self {
        self.reply(&frame_data(frame), after_ms)
    }

    /// Adds: answer with raw bytes (garbage, broken frames), `after_ms` after the end of the last
    /// matched frame.
    pub fn reply_raw(mut self, bytes: &[u8], after_ms: f64) -> Self {
        self.steps.push(Step::Reply {
            bytes: bytes.to_vec(),
            after: ms_to_cycles(after_ms),
            what: format!("raw [{}]", hex(bytes)),
        });
        self
    }

    /// Adds: send frame data `frame_data` unsolicited at `at_ms` (absolute simulated time).
    pub fn send_at(mut self, at_ms: f64, frame_data: &[u8]) -> Self {
        let bytes = self.encode(frame_data);
        self.steps.push(Step::SendAt {
            at: ms_to_cycles(at_ms),
            bytes,
            what: format!("frame [{}]", hex(frame_data)),
        });
        self
    }

    /// Adds: send raw bytes unsolicited at `at_ms` (absolute simulated time).
    pub fn send_raw_at(mut self, at_ms: f64, bytes: &[u8]) -> Self {
        self.steps.push(Step::SendAt {
            at: ms_to_cycles(at_ms),
            bytes: bytes.to_vec(),
            what: format!("raw [{}]", hex(bytes)),
        });
        self
    }

    /// Adds: no frame may start within `ms` of the step's start.
    pub fn expect_silence(mut self, ms: f64) -> Self {
        self.steps.push(Step::Silence {
            dur: ms_to_cycles(ms),
        });
        self
    }

    fn encode(&self, frame_data: &[u8]) -> Vec<u8> {
        let mut buf = [0u8; MAX_ENCODED];
        let n = encode_raw(frame_data, self.mode, &mut buf)
            .unwrap_or_else(|e| panic!("cannot encode frame [{}]: {e:?}", hex(frame_data)));
        buf[..n].to_vec()
    }

    /// Every frame the firmware wrote so far.
    pub fn frames(&self) -> &[SeenFrame] {
        &self.frames
    }

    /// Every complete text line the firmware printed so far.
    pub fn lines(&self) -> &[TextLine] {
        self.lines.lines()
    }

    /// The texts of [`ScriptedRadio::lines`].
    pub fn texts(&self) -> Vec<&str> {
        self.lines().iter().map(|l| l.text.as_str()).collect()
    }

    /// Decode errors (bad checksums, truncated frames…) with the cycle they were noticed.
    pub fn decode_errors(&self) -> &[(u64, DecodeError)] {
        &self.errors
    }

    /// What the radio sent: (first byte's earliest cycle, encoded bytes).
    pub fn sent(&self) -> &[(u64, Vec<u8>)] {
        &self.sent
    }

    /// True when every step is complete.
    pub fn is_done(&self) -> bool {
        self.cursor == self.steps.len()
    }

    /// Runs `avr` until cycle `target`, playing the script. Fails at the first violation (and
    /// on every later call), or if the core stops (done or crashed) while steps remain.
    pub fn run_until(&mut self, avr: &mut Avr, target: u64) -> Result<(), ScriptError> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        if !self.started {
            self.started = true;
            self.anchor = avr.cycle();
            self.last_match = self.anchor;
        }
        self.process(avr)?;
        while avr.cycle() < target {
            // Slices of one byte time: a matched frame is seen (and answered) within a byte time
            // of its end; frame times come from the byte timestamps, not from the slices.
            let slice = avr.uart_cycles_per_byte().max(256);
            let mut next = target.min(avr.cycle() + slice);
            if let Some(ev) = self.next_deadline() {
                if ev > avr.cycle() {
                    next = next.min(ev);
                }
            }
            let state = avr.run_until(next);
            self.process(avr)?;
            if !state.is_alive() && avr.cycle() < target {
                if !self.is_done() {
                    let what = match state {
                        State::Crashed => "the firmware crashed",
                        _ => "the firmware stopped (sleep with interrupts off)",
                    };
                    return Err(self.fail(avr.cycle(), what.to_string()));
                }
                break;
            }
        }
        Ok(())
    }

    /// Runs `avr` for `ms` more milliseconds (see [`ScriptedRadio::run_until`]).
    pub fn run_for_ms(&mut self, avr: &mut Avr, ms: f64) -> Result<(), ScriptError> {
        let target = avr.cycle() + ms_to_cycles(ms);
        self.run_until(avr, target)
    }

    /// Runs until every step is complete, failing if that takes more than `timeout_ms`.
    pub fn run_to_end(&mut self, avr: &mut Avr, timeout_ms: f64) -> Result<(), ScriptError> {
        let target = avr.cycle() + ms_to_cycles(timeout_ms);
        while !self.is_done() && avr.cycle() < target {
            let next = target.min(avr.cycle() + ms_to_cycles(1.0));
            self.run_until(avr, next)?;
        }
        if !self.is_done() {
            return Err(self.fail(
                avr.cycle(),
                format!("script not finished after {timeout_ms} ms"),
            ));
        }
        Ok(())
    }

    fn next_deadline(&self) -> Option<u64> {
        match self.steps.get(self.cursor)? {
            Step::Expect { within, .. } => Some(self.anchor + within + 1),
            Step::SendAt { at, .. } => Some(*at),
            Step::Silence { dur } => Some(self.anchor + dur),
            Step::Reply { .. } => None,
        }
    }

    fn fail(&mut self, cycle: u64, got: String) -> ScriptError {
        let expected = match self.steps.get(self.cursor) {
            Some(s @ Step::Expect { .. }) | Some(s @ Step::Silence { .. }) => {
                format!("{s} (step started at {:.3} ms)", cycles_to_ms(self.anchor))
            }
            Some(s) => s.to_string(),
            None => "end of script".to_string(),
        };
        let lines = self.lines.lines();
        let start = lines.len().saturating_sub(5);
        let e = ScriptError {
            step: self.cursor,
            expected,
            got,
            at_ms: cycles_to_ms(cycle),
            recent_lines: lines[start..]
                .iter()
                .map(|l| format!("{:.3} ms: {}", l.ms(), l.text))
                .collect(),
        };
        self.failed = Some(e.clone());
        e
    }

    /// Takes the new UART output and advances the script as far as it can.
    fn process(&mut self, avr: &mut Avr) -> Result<(), ScriptError> {
        let cpb = avr.uart_cycles_per_byte();
        let out = avr.uart_output();
        let new: Vec<_> = out.get(self.consumed..).unwrap_or_default().to_vec();
        self.consumed = out.len();
        for b in new {
            self.ingest(b.cycle, b.byte, cpb);
        }
        let now = avr.cycle();
        loop {
            let Some(step) = self.steps.get(self.cursor) else {
                return Ok(());
            };
            match step {
                Step::Expect { m, within } => {
                    let deadline = self.anchor + within;
                    match self.frames.get(self.next_frame) {
                        Some(f) if f.end_cycle > deadline => {
                            let got = format!("nothing by the deadline; next was {f}");
                            return Err(self.fail(deadline, got));
                        }
                        Some(f) if m.matches(f) => {
                            self.anchor = f.end_cycle;
                            self.last_match = f.end_cycle;
                            self.next_frame += 1;
                        }
                        Some(f) => {
                            let (c, got) = (f.end_cycle, f.to_string());
                            return Err(self.fail(c, got));
                        }
                        None if now > deadline && !self.decoder.in_frame() => {
                            let got = format!(
                                "no frame by {:.3} ms (now {:.3} ms)",
                                cycles_to_ms(deadline),
                                cycles_to_ms(now)
                            );
                            return Err(self.fail(now, got));
                        }
                        None => return Ok(()),
                    }
                }
                Step::Reply { bytes, after, .. } => {
                    let at = self.last_match + after;
                    let bytes = bytes.clone();
                    avr.uart_send_at(at, &bytes);
                    self.sent.push((at, bytes));
                    self.anchor = at;
                }
                Step::SendAt { at, bytes, .. } => {
                    if now < *at {
                        return Ok(());
                    }
                    let (at, bytes) = (*at, bytes.clone());
                    avr.uart_send_at(at, &bytes);
                    self.sent.push((at, bytes));
                    self.anchor = at;
                }
                Step::Silence { dur } => {
                    let end = self.anchor + dur;
                    if let Some(f) = self.frames.get(self.next_frame) {
                        if f.cycle < end {
                            let got = f.to_string();
                            return Err(self.fail(f.cycle, got));
                        }
                    }
                    if now < end || (self.decoder.in_frame() && self.frame_start < end) {
                        return Ok(());
                    }
                    self.anchor = end;
                }
            }
            self.cursor += 1;
        }
    }

    fn ingest(&mut self, cycle: u64, byte: u8, cpb: u64) {
        let text = !self.decoder.in_frame() && byte != xbee_api::START;
        self.lines.push(cycle, byte, text);
        // Cannot fail: the decoder is polled empty after every byte.
        let _ = self.decoder.push(byte);
        while let Some(ev) = self.decoder.poll() {
            match ev {
                Ok(raw) => self.frames.push(SeenFrame {
                    cycle: self.frame_start,
                    end_cycle: cycle + cpb,
                    data: raw.data().to_vec(),
                }),
                Err(DecodeError::Garbage { .. }) => {}
                Err(e) => self.errors.push((cycle, e)),
            }
        }
        if byte == xbee_api::START && self.decoder.in_frame() {
            self.frame_start = cycle;
        }
    }
}

/// The frame data (type byte first) of `frame`.
pub fn frame_data(frame: &Frame<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED];
    let n = frame
        .encode(Mode::Api, &mut buf)
        .unwrap_or_else(|e| panic!("cannot encode {frame:?}: {e:?}"));
    buf[3..n - 1].to_vec()
}

fn hex(d: &[u8]) -> String {
    d.iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn ms(c: u64) -> f64 {
    (cycles_to_ms(c) * 1000.0).round() / 1000.0
}

#[cfg(test)]
mod line_tests {
    use super::*;

    fn split(bytes: &[(f64, u8, bool)]) -> Vec<(f64, String)> {
        let mut s = LineSplitter::default();
        for &(ms, b, text) in bytes {
            s.push(ms_to_cycles(ms), b, text);
        }
        s.lines().iter().map(|l| (l.ms(), l.text.clone())).collect()
    }

    fn at(ms: f64, text: &str) -> Vec<(f64, u8, bool)> {
        text.bytes()
            .enumerate()
            .map(|(i, b)| (ms + i as f64 * 0.2, b, true))
            .collect()
    }

    #[test]
    fn cr_lf_and_crlf_each_end_one_line() {
        let mut input = at(0.0, "a\r\nb\rc\nd\r\r\ne");
        input.extend(at(1.0, "\n"));
        let texts: Vec<String> = split(&input).into_iter().map(|(_, t)| t).collect();
        assert_eq!(texts, ["a", "b", "c", "d", "e"]);
    }

    #[test]
    fn a_pause_ends_a_line_and_frames_are_skipped() {
        let mut input = at(0.0, "+++");
        input.extend(at(1200.0, "ATCN\r"));
        input.extend([(1300.0, b'x', false), (1300.1, b'y', false)]);
        input.extend(at(1300.2, "ok\r\n"));
        let lines = split(&input);
        assert_eq!(
            lines.iter().map(|(_, t)| t.as_str()).collect::<Vec<_>>(),
            ["+++", "ATCN", "ok"]
        );
        assert!(
            (lines[1].0 - 1200.0).abs() < 0.01,
            "a line is timed by its first byte"
        );
        // An unfinished line stays pending until its end or a pause.
        assert!(split(&at(0.0, "half")).is_empty());
    }
}
