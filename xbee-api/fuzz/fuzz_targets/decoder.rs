//! Arbitrary byte streams through the decoder in both API modes, with idle-line events, checking
//! the invariants the rest of hoploc relies on.
#![no_main]

use libfuzzer_sys::fuzz_target;
use xbee_api::{Decoder, Frame, Mode, MAX_ENCODED, MAX_FRAME_DATA};

fuzz_target!(|input: &[u8]| {
    // First byte picks the mode and how often the line goes idle.
    let Some((&ctl, bytes)) = input.split_first() else {
        return;
    };
    let mode = if ctl & 1 == 0 { Mode::Api } else { Mode::Escaped };
    let idle_every = (ctl >> 1) as usize;
    let mut dec = Decoder::new(mode);
    let mut emitted = 0u32;
    let mut out = [0u8; MAX_ENCODED];
    for (i, &b) in bytes.iter().enumerate() {
        dec.push(b).expect("push after draining never fails");
        if idle_every != 0 && i % idle_every == 0 {
            dec.idle();
        }
        while let Some(ev) = dec.poll() {
            let Ok(raw) = ev else { continue };
            emitted += 1;
            let data = raw.data();
            assert!(!data.is_empty() && data.len() <= MAX_FRAME_DATA);
            // Every frame that parses re-encodes to a frame that decodes to the same data.
            if let Ok(frame) = raw.parse() {
                assert_eq!(frame.data_len(), data.len());
                let n = frame.encode(mode, &mut out).expect("a decoded frame always fits");
                let mut again = Decoder::new(mode);
                let mut same = false;
                again.feed(&out[..n], |ev| same = ev.map(|r| r.data() == data).unwrap_or(false));
                assert!(same, "re-encoded frame did not decode to the same data");
                assert_eq!(Frame::parse(data).ok(), Some(frame));
            }
        }
    }
    assert_eq!(dec.stats().frames, emitted);
});
