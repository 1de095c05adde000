//! The sink's whole per-report path (`est-sink`): the benchmark's inputs as the
//! `loc_proto::msg::Report` an agent sends, through `sink_fw::Sink::on_report`, written as the
//! sink's text lines. The same function runs on the MCU (AVR cost kernel) and on the host (the
//! portable one), so the host's bytes are what the firmware must print.

use crate::{Inputs, N_ANCHORS, N_CHANNELS};
use loc_core::fixed::{AreaCm, TermKernel};
use loc_proto::msg::{ChannelList, Position, Report};
use loc_proto::sink_line::SinkLine;
use sink_fw::{no_fix_line, Sink};

/// The benchmark's channels (the default channel list).
const CHANNELS: ChannelList = match ChannelList::new(&[1, 12]) {
    Ok(c) => c,
    Err(_) => panic!("channel list"),
};

/// Marker written before the timed report and after it (the timed part ends with `\n`).
pub const SINK_MARKS: [u8; 2] = *b"AB";

/// Agent 1's report `seq` of `inp`: every anchor's beacon heard on both channels, the whole relay
/// matrix.
pub fn report(inp: &Inputs, seq: u16) -> Report {
    let mut r = Report::new(1, seq, N_ANCHORS as u8, CHANNELS);
    for i in 0..N_ANCHORS {
        let [x, y] = inp.anchors[i];
        r.positions[i] = Position { x, y };
        for c in 0..N_CHANNELS {
            r.rssi[c][i] = inp.agent[i][c];
            for j in (0..N_ANCHORS).filter(|&j| j != i) {
                r.relay[c][i][j] = inp.a2a_byte(i, j, c);
            }
        }
    }
    r
}

/// Two reports (seq 1, untimed: the AR(1) smoothers then take their steady-state path; seq 2
/// between the two [`SINK_MARKS`], each written through `mark`); returns the second report's
/// sink lines (two `fix` lines, or a `nofix` line).
#[inline(never)]
pub fn run_sink<K: TermKernel>(inp: &Inputs, mut mark: impl FnMut(u8)) -> [Option<SinkLine>; 2] {
    let area = AreaCm::new(inp.area[0], inp.area[1]);
    let mut sink = Sink::<K>::new(Some(area));
    // One report, sent twice (seq 1, then 2): one copy of the bench's scaffolding in flash.
    let mut second = report(core::hint::black_box(inp), 1);
    let _ = core::hint::black_box(sink.on_report(core::hint::black_box(&second)));
    second.seq = 2;
    mark(SINK_MARKS[0]);
    let fix = sink.on_report(core::hint::black_box(&second));
    let fix = core::hint::black_box(fix);
    mark(SINK_MARKS[1]);
    match fix {
        Ok(f) => f.lines().map(Some),
        Err(e) => [Some(no_fix_line(second.agent, second.seq, e)), None],
    }
}

/// `\n` (the end of the timed part), then `lines` as the sink writes them.
pub fn write_lines<W: ufmt::uWrite + ?Sized>(
    lines: &[Option<SinkLine>; 2],
    out: &mut W,
) -> Result<(), W::Error> {
    out.write_str("\n")?;
    for line in lines.iter().flatten() {
        line.write(out)?;
    }
    Ok(())
}
