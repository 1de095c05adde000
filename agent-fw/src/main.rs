//! agent-fw: the hoploc agent firmware for the Arduino Uno.
//!
//! Wiring only (the logic is `agent_fw::Agent`, host-tested): `uno_board::boot` (boot line,
//! node config, radio bring-up, watchdog), then the loop — feed the µs clock to the agent and
//! do what it asks (tune to an anchor channel or the sink channel, send the report to the
//! sink), feed it the beacons and TX statuses the radio hands over, idle until its next event.
//! Build: `cargo fw` (all firmwares); build and flash: `cargo run` in this directory, or
//! `cargo fw-run -p agent-fw` from the workspace root.
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
    use agent_fw::Agent;
    use loc_proto::schedule::{beacon_latency_us, Schedule};
    use loc_proto::Role;
    use uno_board::{now_us, reset};

    uno_board::boot(Role::Agent, built_in::BUILT_IN, |node| {
        let config = &node.config;
        let Ok(sched) = Schedule::for_config(config) else {
            reset()
        };
        let latency = beacon_latency_us(config.anchors);
        let agent = Agent::new(config.id, sched, config.channels, latency, now_us());
        run(agent, node)
    })
}

/// The node's loop, out of line: on the AVR every access beyond 63 bytes into a stack frame
/// costs extra code, and `main`'s frame is big with the bring-up's state.
#[cfg(target_arch = "avr")]
#[inline(never)]
fn run(mut agent: agent_fw::Agent, node: &mut uno_board::Node) -> ! {
    use agent_fw::{Action, Agent, Heard, Tune};
    use loc_proto::msg::{Beacon, MAX_PAYLOAD};
    use loc_proto::Role;
    use uno_board::node::{self, Event};
    use uno_board::prelude::*;
    use uno_board::{now_us, NodeRadio};
    let uno_board::Node {
        radio,
        led,
        watchdog,
        config,
    } = node;
    let channels = config.channels;
    let sink = Role::Sink.address(1);
    let act = |radio: &mut NodeRadio, agent: &Agent, action: Action| match action {
        Action::Tune(Tune::List(c)) => {
            if let Some(&n) = channels.as_slice().get(c as usize) {
                let _ = node::tune(radio, n);
            }
        }
        Action::Tune(Tune::Sink) => {
            let _ = node::tune(radio, config.sink_channel);
        }
        Action::SendReport { .. } => {
            let mut buf = [0u8; MAX_PAYLOAD];
            if let Ok(n) = agent.report().encode(&mut buf) {
                let _ = node::send(radio, sink, &buf[..n]);
            }
        }
    };
    loop {
        watchdog.feed();
        while let Some(action) = agent.poll(now_us()) {
            act(radio, &agent, action);
            if let Action::SendReport { .. } = action {
                let Ok(()) = led.toggle();
            }
        }
        // What arrived: a beacon goes to the agent inside the poll (it borrows the frame); a TX
        // status comes out, and the action it gives is done after.
        while let Some(status) = node::poll(radio, |ev, _| match ev {
            Event::Packet {
                rssi, data, at_us, ..
            } => {
                if let Ok(b) = Beacon::decode(data) {
                    if let Some(c) = channels.as_slice().iter().position(|&c| c == b.channel) {
                        agent.on_beacon(Heard {
                            from: b.anchor,
                            seq: b.seq,
                            channel: c as u8,
                            rssi: rssi.max(1),
                            at_us,
                            pos: [b.position.x, b.position.y],
                            relay: &b.relay,
                        });
                    }
                }
                None
            }
            Event::TxStatus(ok) => Some(ok),
            Event::Other => None,
        }) {
            if let Some(action) = status.and_then(|ok| agent.on_tx_status(ok)) {
                act(radio, &agent, action);
            }
        }
        node::idle(agent.wait_us(now_us()));
    }
}
