//! Arbitrary text through the line parsers the host tools use (the sink's lines, the boot
//! lines): they never panic, and a line that parses is written back to the same text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use loc_proto::line::BootLine;
use loc_proto::sink_line::{RawReport, SinkOutput};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let mut out = String::new();
    match SinkOutput::parse(text) {
        Ok(SinkOutput::Line(l)) => {
            let Ok(()) = l.write(&mut out);
            assert_eq!(out.strip_suffix("\r\n").unwrap(), text.trim_end_matches(['\r', '\n']));
        }
        Ok(SinkOutput::Report(r)) => {
            let Ok(()) = RawReport::write(r.bytes(), &mut out);
            assert_eq!(out.strip_suffix("\r\n").unwrap(), text.trim_end_matches(['\r', '\n']));
        }
        Err(_) => {}
    }
    let _ = BootLine::parse(text);
});
