//! anchor-fw: the hoploc anchor firmware for the Arduino Uno.
//!
//! Wiring only (the logic is `anchor_fw::Anchor`, host-tested): `uno_board::boot` (boot line,
//! node config, radio bring-up, watchdog), then the loop — feed the µs clock to the anchor and
//! do what it asks (tune, send a beacon), feed it the beacons the radio hears, idle until its
//! next event. Build: `cargo fw` (all firmwares); build and flash: `cargo run` in this
//! directory, or `cargo fw-run -p anchor-fw` from the workspace root.
#![cfg_attr(target_arch = "avr", no_std, no_main)]

#[cfg(not(target_arch = "avr"))]
fn main() {}

#[cfg(target_arch = "avr")]
uno_board::link_avr_libc!();

/// The build-time config (`BUILT_IN`) and its `.eeprom` image, from build.rs.
#[cfg(target_arch = "avr")]
mod built_in {
    include!(concat!(env!("OUT_DIR"), "/config.rs"));
}

#[cfg(target_arch = "avr")]
#[uno_board::entry]
fn main() -> ! {
    use anchor_fw::Anchor;
    use loc_proto::schedule::{beacon_latency_us, Schedule};
    use loc_proto::Role;
    use uno_board::{now_us, reset};

    uno_board::boot(Role::Anchor, built_in::BUILT_IN, |node| {
        let config = &node.config;
        let Ok(sched) = Schedule::for_config(config) else {
            reset()
        };
        let anchor = Anchor::new(
            config.id,
            sched,
            beacon_latency_us(config.anchors),
            now_us(),
        );
        run(anchor, node)
    })
}

/// The node's loop, out of line: `main`'s frame holds the bring-up's state, and on the AVR
/// every access beyond 63 bytes into a frame costs extra code.
#[cfg(target_arch = "avr")]
#[inline(never)]
fn run(mut anchor: anchor_fw::Anchor, node: &mut uno_board::Node) -> ! {
    use anchor_fw::{Action, Heard};
    use loc_proto::msg::Beacon;
    use uno_board::node::{self, Event};
    use uno_board::now_us;
    use uno_board::prelude::*;
    let uno_board::Node {
        radio,
        led,
        watchdog,
        config,
    } = node;
    let channels = config.channels;
    loop {
        watchdog.feed();
        while let Some(action) = anchor.poll(now_us()) {
            match action {
                Action::SetChannel(c) => {
                    if let Some(&n) = channels.as_slice().get(c as usize) {
                        let _ = node::tune(radio, n);
                    }
                }
                Action::SendBeacon { seq, channel } => {
                    let beacon = anchor.beacon(seq, channel, &channels, config.position);
                    let mut buf = [0u8; Beacon::MAX_LEN];
                    if let Ok(n) = beacon.encode(&mut buf) {
                        let _ = node::send(radio, loc_proto::BROADCAST, &buf[..n]);
                    }
                    let Ok(()) = led.toggle();
                }
            }
        }
        while let Some(heard) = node::poll(radio, |ev, _| match ev {
            Event::Packet {
                rssi, data, at_us, ..
            } => {
                let b = Beacon::decode(data).ok()?;
                let channel = channels.as_slice().iter().position(|&c| c == b.channel)?;
                Some(Heard {
                    from: b.anchor,
                    seq: b.seq,
                    channel: channel as u8,
                    rssi: rssi.max(1),
                    at_us,
                })
            }
            _ => None,
        }) {
            if let Some(h) = heard {
                anchor.on_beacon(h);
            }
        }
        node::idle(anchor.wait_us(now_us()));
    }
}
