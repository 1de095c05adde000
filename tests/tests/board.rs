//! uno-board on the simulated Uno: the LED through embedded-hal's pin traits, `Delay` through
//! `DelayNs`, the UART receive ring when it is full and when it streams (the `board-check`
//! firmware of mcu-bench, steps as `mcu_bench::board` describes), and the cycles the interrupt
//! handlers take in the node firmwares against the time between two bytes at 57600 baud.

use std::sync::OnceLock;

use hoploc_tests::{boot, led_on};
use loc_proto::Role;
use mcu_bench::board::{
    led_states, DelayKind, DELAYS, FULL_SENT, FULL_WAIT_MS, LED_STEPS, STREAM_LEN,
};
use mcu_bench::harness;
use simavr::{ms_to_cycles, Avr};

/// `cargo fw-bench`, once per test process (a no-op when the ELFs are current).
static BUILD: OnceLock<Result<(), String>> = OnceLock::new();

/// CPU cycles per µs at 16 MHz.
const CYCLES_PER_US: u64 = 16;

fn board_check() -> Avr {
    if let Err(e) = BUILD.get_or_init(harness::build) {
        panic!("bench firmware: {e}");
    }
    let elf = harness::elf("board-check");
    Avr::load(&elf).unwrap_or_else(|e| panic!("{}: {e}", elf.display()))
}

/// Runs `avr` in steps of `step` cycles until it has written `n` bytes; panics after `limit_ms`.
fn run_until_output(avr: &mut Avr, n: usize, step: u64, limit_ms: f64) {
    let end = avr.cycle() + ms_to_cycles(limit_ms);
    while avr.uart_output().len() < n {
        assert!(
            avr.cycle() < end && avr.state().is_alive(),
            "{} bytes written, waiting for {n}: {:?}",
            avr.uart_output().len(),
            avr.uart_output_string()
        );
        avr.run_for(step);
    }
}

#[test]
fn the_led_follows_the_embedded_hal_pin_traits() {
    let mut avr = board_check();
    let states = led_states();
    assert!(!led_on(&avr));
    for (k, (step, &on)) in LED_STEPS.iter().zip(&states).enumerate() {
        // The two state bytes of step k; PB5 is sampled within 64 cycles of the second (the
        // firmware waits a byte time after each, then 1 ms).
        run_until_output(&mut avr, 2 * k + 2, 64, 100.0);
        let out = avr.uart_output();
        let said = [out[2 * k].byte, out[2 * k + 1].byte];
        assert_eq!(
            said,
            [b'0' + u8::from(on), b'0' + u8::from(!on)],
            "step {k} ({step:?}): is_set_high, is_set_low"
        );
        assert_eq!(led_on(&avr), on, "step {k} ({step:?}): PB5");
    }
}

#[test]
fn delays_wait_at_least_what_they_are_asked_and_little_more() {
    let mut avr = board_check();
    let d = 2 * LED_STEPS.len();
    // 'D', the pair without a delay, then a pair per case.
    let total = d + 3 + 2 * DELAYS.len();
    // The delays add up to ≈ 134 s.
    run_until_output(&mut avr, total, 100_000, 140_000.0);
    let out = avr.uart_output();
    assert_eq!(out[d].byte, b'D', "{:?}", avr.uart_output_string());
    let pair = |k: usize| {
        let (a, b) = (out[d + 1 + 2 * k], out[d + 2 + 2 * k]);
        assert_eq!((a.byte, b.byte), (b'<', b'>'), "pair {k}");
        b.cycle - a.cycle
    };
    // The pairs' own cost (the first byte's time on the line and the calls), measured.
    let base = pair(0);
    let mut report = vec![format!("no delay: {base} cycles")];
    for (i, &(kind, n)) in DELAYS.iter().enumerate() {
        let took = pair(i + 1).saturating_sub(base);
        // What was asked, in cycles, and how much more is allowed: up to the tick that ends a
        // `delay_ms` (1 ms); a 4 µs step of the µs clock and its reads (≈ 6 µs each) for the
        // others; 8 cycles either way for the polling of the line in the pairs.
        let (asked, slack) = match kind {
            DelayKind::Ms => (u64::from(n) * 1_000 * CYCLES_PER_US, 1_000 * CYCLES_PER_US),
            DelayKind::Us => (u64::from(n) * CYCLES_PER_US, 25 * CYCLES_PER_US),
            // `delay_ns` waits whole µs, 2 more, and up to 0.7 % more (1 % allowed).
            DelayKind::Ns => (
                u64::from(n) * CYCLES_PER_US / 1_000,
                (u64::from(n) / 100_000 + 28) * CYCLES_PER_US,
            ),
        };
        report.push(format!("{kind:?}({n}): {took} cycles"));
        assert!(
            took + 8 >= asked,
            "{kind:?}({n}) took {took} cycles, under the {asked} asked"
        );
        assert!(
            took <= asked + slack + 200,
            "{kind:?}({n}) took {took} cycles, {} over the {asked} asked",
            took - asked
        );
    }
    eprintln!("{}", report.join("\n"));
}

/// Bytes that differ from their neighbours and include frame delimiters (0x7E), but no `\n`
/// (which ends the full-ring phase's echo).
fn pattern(n: usize, seed: u8) -> Vec<u8> {
    (0..n)
        .map(|i| match (i as u8).wrapping_mul(29).wrapping_add(seed) {
            _ if i % 37 == 5 => 0x7E,
            b'\n' => 0,
            b => b,
        })
        .collect()
}

/// Runs board-check to its 'R' and returns the index of it in the output.
fn run_to_full_ring_phase(avr: &mut Avr) -> usize {
    let r = 2 * LED_STEPS.len() + 3 + 2 * DELAYS.len();
    run_until_output(avr, r + 1, 100_000, 140_000.0);
    assert_eq!(avr.uart_output()[r].byte, b'R');
    r
}

#[test]
fn a_full_rx_ring_keeps_the_oldest_bytes_and_a_stream_passes_whole() {
    let mut avr = board_check();
    let r = run_to_full_ring_phase(&mut avr);
    // While the firmware does not read for FULL_WAIT_MS, FULL_SENT bytes arrive (≈ 39 ms): the
    // ring keeps the first RX_BUFFER_SIZE of them and drops the rest.
    let full = pattern(FULL_SENT, 3);
    avr.uart_send(&full);
    avr.run_for_ms(f64::from(FULL_WAIT_MS) + 10.0);
    let nl = |avr: &Avr| {
        avr.uart_output()
            .iter()
            .skip(r)
            .position(|b| b.byte == b'\n')
    };
    while nl(&avr).is_none() {
        assert!(avr.state().is_alive());
        avr.run_for_ms(5.0);
    }
    let out = avr.uart_output();
    let echoed: Vec<u8> = out[r + 1..r + nl(&avr).unwrap()]
        .iter()
        .map(|b| b.byte)
        .collect();
    assert_eq!(echoed, full[..uno_board::RX_BUFFER_SIZE]);
    // Then a stream at the line's full rate, read as it comes: every byte, in order.
    let s = r + nl(&avr).unwrap() + 5;
    run_until_output(&mut avr, s + 1, 1_000, 100.0);
    assert_eq!(avr.uart_output()[s].byte, b'S');
    let stream = pattern(STREAM_LEN, 11);
    avr.uart_send(&stream);
    let end = s + 1 + STREAM_LEN + 4 + 4;
    run_until_output(&mut avr, end, 10_000, 1_000.0);
    let out = avr.uart_output();
    let echoed: Vec<u8> = out[s + 1..s + 1 + STREAM_LEN]
        .iter()
        .map(|b| b.byte)
        .collect();
    assert_eq!(echoed, stream);
    // The stamp of the last 0x7E: when its byte was complete on the line (simavr raises RXC0
    // one byte time after the byte's start), on the firmware's µs clock, which read `t0` just
    // before the first of its four bytes was written.
    let le = |i: usize| u32::from_le_bytes(std::array::from_fn(|k| out[i + k].byte));
    let (t0, stamp) = (le(s - 4), le(s + 1 + STREAM_LEN));
    let last = stream.iter().rposition(|&b| b == 0x7E).unwrap();
    let input = avr.uart_input();
    let arrived = input[input.len() - STREAM_LEN + last].cycle + avr.uart_cycles_per_byte();
    let want_us = i64::from(t0) + (arrived as i64 - out[s - 4].cycle as i64) / 16;
    let off = i64::from(stamp) - want_us;
    assert!(
        (-8..=40).contains(&off),
        "frame start stamped {off} µs from the byte's arrival"
    );
}

/// The data-space address of SPL (SPH follows).
const SPL: usize = 0x5D;
/// The cycles an interrupt costs before its handler's first instruction: the response (4, the
/// datasheet's minimum) and the vector table's `jmp` (3).
const ENTRY_CYCLES: u64 = 4 + 3;

fn sp(avr: &Avr) -> usize {
    let d = avr.data();
    usize::from(d[SPL]) | usize::from(d[SPL + 1]) << 8
}

/// Runs `avr` one instruction at a time for `cycles` and returns, for each handler of
/// `handlers` (symbol names), the cycles of each of its runs: from its first instruction
/// through its `reti`, plus [`ENTRY_CYCLES`].
fn handler_cycles(avr: &mut Avr, handlers: &[&str], cycles: u64) -> Vec<Vec<u64>> {
    let starts: Vec<u32> = handlers
        .iter()
        .map(|h| avr.symbol(h).unwrap_or_else(|| panic!("no {h}")))
        .collect();
    let end = avr.cycle() + cycles;
    let mut runs = vec![Vec::new(); handlers.len()];
    let mut open: Option<(usize, u64, usize)> = None;
    while avr.cycle() < end && avr.state().is_alive() {
        if open.is_none() {
            if let Some(h) = starts.iter().position(|&s| avr.pc() == s) {
                open = Some((h, avr.cycle(), sp(avr)));
            }
        }
        let c = avr.cycle();
        avr.run_until(c + 1);
        if let Some((h, c0, sp0)) = open {
            // `reti` pops the return address: the stack is back above where the handler began.
            if sp(avr) > sp0 {
                runs[h].push(avr.cycle() - c0 + ENTRY_CYCLES);
                open = None;
            }
        }
    }
    runs
}

/// Cycles between two bytes at 57600 baud on the 16 MHz Uno.
const BYTE_CYCLES: u64 = 16_000_000 * 10 / 57_600;

/// The RX handler in the node firmwares (the anchor's and the agent's stamp frame starts, the
/// sink's does not need to) and the tick, measured while bytes stream in during the provisioning
/// window: each run must take a small part of the time between two bytes, so the ring keeps up
/// at 57600 baud even after the main program's longest critical section.
#[test]
fn interrupt_handlers_take_a_small_part_of_a_byte_time() {
    let mut lines = Vec::new();
    for role in [Role::Anchor, Role::Agent, Role::Sink] {
        let mut avr = boot(role);
        avr.run_for_ms(100.0);
        let bytes = pattern(150, 7);
        avr.uart_send(&bytes);
        let runs = handler_cycles(
            &mut avr,
            &["__vector_14", "__vector_18"],
            ms_to_cycles(40.0),
        );
        let (tick, rx) = (&runs[0], &runs[1]);
        assert_eq!(rx.len(), bytes.len(), "{role:?}: one RX interrupt per byte");
        assert!(tick.len() >= 39, "{role:?}: a tick per ms");
        let stats = |r: &[u64]| (r.iter().min().copied(), r.iter().max().copied());
        let ((rx_min, rx_max), (tick_min, tick_max)) = (stats(rx), stats(tick));
        lines.push(format!(
            "{role:?}: USART_RX {rx_min:?}..{rx_max:?} cycles, TIMER0_COMPA {tick_min:?}..{tick_max:?} \
             (entry included), a byte every {BYTE_CYCLES}"
        ));
        let (rx_max, tick_max) = (rx_max.unwrap(), tick_max.unwrap());
        assert!(
            rx_max + tick_max + 8 < BYTE_CYCLES / 10,
            "{role:?}: RX {rx_max} + tick {tick_max} cycles"
        );
    }
    eprintln!("{}", lines.join("\n"));
}
