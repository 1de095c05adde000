//! Arbitrary EEPROM contents and provisioning streams: the config decoder and the provisioning
//! parser never panic; a config that decodes re-encodes to the same bytes and is valid; the
//! parser's verdict on a frame is the config decoder's on its bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use loc_proto::config::{stored, Config};
use loc_proto::provision::{self, ProvisionParser, Reply};
use loc_proto::Role;

fuzz_target!(|data: &[u8]| {
    let mut buf = [0u8; 64];
    if let Ok(c) = Config::from_bytes(data) {
        assert_eq!(c.validate(), Ok(()));
        let n = c.to_bytes(&mut buf).expect("a decoded config re-encodes");
        assert_eq!(&buf[..n], &data[..n]);
        // What a node stores it provisions, and the frame of it parses back to it.
        let mut frame = [0u8; 96];
        let k = provision::encode(&c, &mut frame).expect("a valid config frames");
        let mut p = ProvisionParser::new();
        let got: Vec<_> = frame[..k].iter().filter_map(|&b| p.push(b)).collect();
        assert_eq!(got, [Ok(c)]);
    }
    for role in [Role::Anchor, Role::Agent, Role::Sink] {
        let _ = stored(data, role);
    }
    let mut p = ProvisionParser::new();
    for &b in data {
        if let Some(outcome) = p.push(b) {
            let _ = Reply::to(&outcome);
            let (_, keep) = provision::answer(outcome, Role::Anchor);
            if let Some(c) = keep {
                assert_eq!(c.role, Role::Anchor);
                assert_eq!(c.validate(), Ok(()));
            }
        }
    }
    let _ = Reply::parse(data);
});
