//! Each firmware brings up a modelled XBee S1 as a user may find it (`simavr::xbee`): left at
//! any of the S1's baud rates in transparent mode (`BD=7` at the 111 111 bit/s the S1 really
//! runs), or in API mode with another owner's settings (XBee retries, another MAC mode, a sleep
//! mode, end-device association, low output power, another channel access, encryption on).
//! After bring-up the radio must run as hoploc expects (an anchor's beacons on air once, at full
//! power, and another anchor heard), and its flash must be written only when its mode or rate had
//! to change. A radio left in pin sleep is out of a node's reach.

use hoploc_tests::{beacon_packet, beacons_sent, boot};
use loc_proto::config::Config;
use loc_proto::line::{BootLine, RadioFound};
use loc_proto::provision::PROVISION_WINDOW_MS;
use loc_proto::schedule::Schedule;
use loc_proto::Role;
use simavr::xbee::{RxPacket, Transmission, XBee, XBeeConfig, XBeeStats, BAUD_RATES};
use simavr::{ms_to_cycles, Avr};
use xbee_api::driver::FIXED_SETTINGS;

/// Runs `role` against `radio` until its radio line; returns what the line says: the radio
/// found, or the error code of a failed bring-up.
fn radio_line(
    role: Role,
    radio: &mut XBee,
    avr: &mut Avr,
    budget_ms: f64,
) -> Result<RadioFound, u8> {
    let deadline = PROVISION_WINDOW_MS as f64 + budget_ms;
    loop {
        radio.run_for_ms(avr, 20.0);
        for l in radio.text_lines() {
            match BootLine::parse(&l.text) {
                Ok(BootLine::RadioUp { found, .. }) => return Ok(found),
                Ok(BootLine::RadioError { code, .. }) => return Err(code),
                _ => {}
            }
        }
        assert!(
            avr.time_ms() < deadline,
            "{role:?}: no radio line: {:?}",
            radio.texts()
        );
    }
}

/// Runs `role` against `radio` until its radio line; returns the radio found.
fn bring_up(role: Role, radio: &mut XBee, avr: &mut Avr, budget_ms: f64) -> RadioFound {
    radio_line(role, radio, avr, budget_ms)
        .unwrap_or_else(|code| panic!("{role:?}: radio error {code}: {:?}", radio.texts()))
}

/// A radio left at `bd` in transparent mode (as from the factory, at another rate).
fn found_at(bd: u32) {
    let role = Role::Anchor;
    let mut avr = boot(role);
    let mut radio = XBee::new(XBeeConfig {
        bd,
        ..XBeeConfig::default()
    });
    // Eight rates at most, each 2.7 s of guard times and waiting.
    let found = bring_up(role, &mut radio, &mut avr, 25_000.0);
    let baud = BAUD_RATES[bd as usize];
    assert_eq!(found, RadioFound::Configured { baud }, "BD={bd}");
    let r = radio.core().persisted();
    assert_eq!(
        (r.ap(), r.bd()),
        (2, 6),
        "written once: API mode 2 at 57600"
    );
    assert!(radio.core().baud_matches());
}

#[test]
fn a_radio_left_at_bd_0_is_found() {
    found_at(0);
}
#[test]
fn a_radio_left_at_bd_1_is_found() {
    found_at(1);
}
#[test]
fn a_radio_left_at_bd_2_is_found() {
    found_at(2);
}
#[test]
fn a_radio_left_at_bd_4_is_found() {
    found_at(4);
}
#[test]
fn a_radio_left_at_bd_5_is_found() {
    found_at(5);
}
#[test]
fn a_radio_left_at_bd_7_is_found_at_111111_baud() {
    assert_eq!(BAUD_RATES[7], 111_111);
    found_at(7);
}

/// A second-hand radio in API mode 2 at 57600 with another owner's settings: every node gives it
/// the factory behaviour back, in its active registers only (nothing written to its flash).
fn second_hand(role: Role) {
    let leftovers = vec![
        (*b"RR", 3),
        (*b"MM", 1),
        (*b"SM", 4),
        (*b"A1", 4),
        (*b"PL", 0),
        (*b"RN", 3),
        (*b"CA", 0x24),
        (*b"EE", 1),
    ];
    let mut avr = boot(role);
    let mut radio = XBee::new(XBeeConfig {
        leftovers: leftovers.clone(),
        ..XBeeConfig::api(2)
    });
    assert_eq!(
        bring_up(role, &mut radio, &mut avr, 1_000.0),
        RadioFound::Api
    );
    let active = radio.registers();
    for &(cmd, value) in &FIXED_SETTINGS {
        assert_eq!(
            active.get(cmd),
            Some(u32::from(value)),
            "{role:?}: AT{cmd:?}"
        );
    }
    let (rn, ca) = match role {
        Role::Agent => (
            loc_proto::schedule::AGENT_BACKOFF_EXPONENT,
            loc_proto::schedule::AGENT_CCA_THRESHOLD,
        ),
        _ => (0, xbee_api::driver::FACTORY_CCA_THRESHOLD),
    };
    assert_eq!(active.get(*b"RN"), Some(u32::from(rn)));
    assert_eq!(active.get(*b"CA"), Some(u32::from(ca)));
    assert!(!active.ee(), "no network key: encryption off");
    // Nothing written: the leftovers are still what a power cycle brings back.
    let persisted = radio.core().persisted();
    for &(cmd, value) in &leftovers {
        assert_eq!(
            persisted.get(cmd),
            Some(value),
            "{role:?}: AT{cmd:?} persisted"
        );
    }
}

#[test]
fn a_second_hand_anchor_radio_gets_the_factory_behaviour() {
    second_hand(Role::Anchor);
}
#[test]
fn a_second_hand_agent_radio_gets_the_factory_behaviour() {
    second_hand(Role::Agent);
}
#[test]
fn a_second_hand_sink_radio_gets_the_factory_behaviour() {
    second_hand(Role::Sink);
}

/// What an anchor did on a radio: its beacon frames, the packets its radio put on air, whether
/// its radio passed on another anchor's beacon, and its radio's counters.
struct AnchorRun {
    beacons: usize,
    sent: Vec<Transmission>,
    heard: bool,
    stats: XBeeStats,
}

/// Anchor 1 (the built-in config) on a radio in API mode 2 at 57600 left with `leftovers`,
/// with `after` set in its active registers once bring-up is done (as if bring-up had left
/// them), for five superframes; anchor 2's beacon reaches its radio while it listens.
fn anchor_on(leftovers: &[([u8; 2], u32)], after: &[([u8; 2], u32)]) -> AnchorRun {
    let role = Role::Anchor;
    let mut avr = boot(role);
    let mut radio = XBee::new(XBeeConfig {
        leftovers: leftovers.to_vec(),
        ..XBeeConfig::api(2)
    });
    assert_eq!(
        bring_up(role, &mut radio, &mut avr, 1_000.0),
        RadioFound::Api
    );
    for &(cmd, v) in after {
        radio.core_mut().registers_mut().set_unchecked(cmd, v);
    }
    // Anchor 1 listens for two superframes before it beacons: another anchor's beacon then.
    let core = radio.core();
    let r = core.registers();
    let beacon = beacon_packet(2, 7, 1, [300, 0], &[0; 4]);
    let packet = RxPacket::broadcast16(
        core.channel(),
        r.id(),
        Role::Anchor.address(2),
        -60,
        &beacon,
    );
    let at = avr.cycle() + ms_to_cycles(100.0);
    let before = radio.stats().rx_delivered;
    radio.deliver(packet, at);
    let superframe = Schedule::for_config(&Config::DEFAULT)
        .unwrap()
        .superframe_us() as f64
        / 1000.0;
    radio.run_for_ms(&mut avr, 5.0 * superframe);
    let stats = radio.stats();
    AnchorRun {
        beacons: beacons_sent(&radio).len(),
        sent: radio.take_transmissions(),
        heard: stats.rx_delivered > before,
        stats,
    }
}

/// The settings of a second-hand radio that change what an anchor's radio does on air: asleep
/// (`SM` 4: deaf), an end device looking for a coordinator (`A1` 4: sends nothing, passes on
/// nothing), the lowest output power (`PL` 0: 10 dB down) and repeated broadcasts (`RR` 3: five
/// copies of each beacon). After bring-up (`FIXED_SETTINGS`) the anchor hears another anchor
/// and puts each beacon on air once at full power, as on a new radio, and its radio's serial
/// buffer never overflows (one frame per slot). With those settings put back after bring-up,
/// what the radio would do without `FIXED_SETTINGS`: deaf and silent; with `RR` 3 and `PL` 0
/// alone, each beacon five times, 10 dB down.
#[test]
fn a_second_hand_anchor_radio_hears_and_beacons_once_at_full_power() {
    let leftovers = [(*b"SM", 4), (*b"A1", 4), (*b"PL", 0), (*b"RR", 3)];
    let fixed = anchor_on(&leftovers, &[]);
    assert!(fixed.beacons >= 3, "{} beacons", fixed.beacons);
    assert!(fixed.heard, "it hears anchor 2");
    assert_eq!(
        fixed.sent.len(),
        fixed.beacons,
        "one transmission per beacon"
    );
    assert!(fixed
        .sent
        .iter()
        .all(|t| t.mac.attempt == 0 && t.power_db == 0));
    let st = fixed.stats;
    assert_eq!(
        (st.repeats, st.tx_associating, st.rx_asleep, st.di_overflow),
        (0, 0, 0, 0)
    );

    // Without the fixed settings: asleep and associating, nothing heard, nothing sent.
    let left = anchor_on(&leftovers, &leftovers);
    assert!(left.beacons >= 3);
    assert!(!left.heard);
    assert!(left.sent.is_empty());
    assert_eq!(left.stats.tx_associating as usize, left.beacons);
    assert_eq!(left.stats.rx_asleep, 1);

    // RR 3 and PL 0 alone: five copies of every beacon at −10 dB.
    let loud = anchor_on(&leftovers, &[(*b"PL", 0), (*b"RR", 3)]);
    assert!(loud.heard);
    assert_eq!(loud.sent.len(), 5 * loud.beacons);
    assert!(loud.sent.iter().all(|t| t.power_db == -10));
    assert_eq!(loud.stats.repeats as usize, 4 * loud.beacons);
    assert_eq!(loud.stats.di_overflow, 0);
}

/// A radio left in a pin sleep mode (`SM` 1, 2) sleeps on a node: the shield leaves `SLEEP_RQ`
/// to the radio's pull-up, and a radio in pin sleep takes nothing from its UART (Digi's S1
/// manual). No node can bring it up, let alone clear `SM`: after trying every rate it reports
/// no answer (error 9). Such a radio needs an XBee USB adapter (`hoploc radio --restore`).
#[test]
fn a_radio_left_in_pin_sleep_cannot_be_brought_up_on_a_shield() {
    for sm in [1, 2] {
        let role = Role::Anchor;
        let mut avr = boot(role);
        let mut radio = XBee::new(XBeeConfig {
            leftovers: vec![(*b"SM", sm)],
            ..XBeeConfig::api(2)
        });
        let no_response = xbee_api::driver::Error::NoResponse.code();
        assert_eq!(
            radio_line(role, &mut radio, &mut avr, 25_000.0),
            Err(no_response),
            "SM {sm}"
        );
        assert!(radio.stats().dropped_asleep > 0);
        assert_eq!(u32::from(radio.registers().sm()), sm);
    }
}
