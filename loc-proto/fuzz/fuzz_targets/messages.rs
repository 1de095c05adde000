//! Arbitrary radio payloads through the message decoders: they never panic, and whatever
//! decodes re-encodes to the very same bytes (one encoding per message, so nothing a node
//! accepts can differ from what a node sends); the sink's in-place parsers agree with the
//! decoder (`ReportView::parse` its error, `ReportView::accept` how that error counts).
#![no_main]

use libfuzzer_sys::fuzz_target;
use loc_proto::msg::{decode_any, Beacon, Message, NotReport, Report, ReportView, MAX_PAYLOAD};

fuzz_target!(|data: &[u8]| {
    let mut buf = [0u8; 2 * MAX_PAYLOAD];
    if let Ok(m) = decode_any(data) {
        let n = m.encode(&mut buf).expect("a decoded message re-encodes");
        assert_eq!(&buf[..n], data, "{m:?}");
        assert_eq!(Message::decode(data), Ok(m));
    }
    if let Ok(b) = Beacon::decode(data) {
        let n = b.encode(&mut buf).expect("a decoded beacon re-encodes");
        assert_eq!(&buf[..n], data);
    }
    if let Ok(r) = Report::decode(data) {
        let n = r.encode(&mut buf).expect("a decoded report re-encodes");
        assert_eq!(&buf[..n], data);
    }
    let view = ReportView::parse(data);
    assert_eq!(view.map(|_| ()), Report::decode(data).map(|_| ()));
    assert_eq!(ReportView::accept(data), view.map_err(NotReport::of));
});
