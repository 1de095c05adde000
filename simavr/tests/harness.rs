//! The `Avr` harness against small C fixtures built with avr-gcc.

mod common;

use std::time::Instant;

use simavr::{ms_to_cycles, Avr, State, F_CPU};

/// 57600 baud nominal, 11 bit times per byte as simavr counts them.
const NOMINAL_CPB: f64 = F_CPU as f64 * 11.0 / 57600.0;

fn load(name: &str) -> Avr {
    Avr::load(common::fixture(name)).unwrap_or_else(|e| panic!("loading {name}: {e}"))
}

#[test]
fn echo_round_trip_at_the_byte_rate() {
    let mut avr = load("echo");
    avr.run_for_ms(1.0);
    let cpb = avr.uart_cycles_per_byte();
    // UBRR0 = 34 with U2X0: 280 cycles per bit, 11 bit times → 3080 (57142 baud), ~3056 nominal.
    assert_eq!(cpb, 3080);
    assert!((cpb as f64 - NOMINAL_CPB).abs() / NOMINAL_CPB < 0.01);

    let t0 = avr.cycle();
    avr.uart_send(b"hello");
    avr.run_for_ms(5.0);
    assert_eq!(avr.uart_output_string(), "hello");
    let input = avr.uart_input().to_vec();
    let output = avr.uart_output().to_vec();
    assert_eq!(input.len(), 5);
    assert_eq!(input[0].cycle, t0);
    for w in input.windows(2) {
        assert_eq!(w[1].cycle - w[0].cycle, cpb, "input paced at the byte time");
    }
    for (i, o) in input.iter().zip(&output) {
        assert_eq!(i.byte, o.byte);
        // RXC0 rises one byte time after the start bit; then ISR, wake-up, UDR0 write.
        let latency = o.cycle - i.cycle;
        assert!(
            (cpb..cpb + 400).contains(&latency),
            "echo latency {latency} cycles"
        );
    }
    for w in output.windows(2) {
        let d = w[1].cycle - w[0].cycle;
        assert!((cpb..cpb + 20).contains(&d), "output spacing {d}");
    }
    assert_eq!(avr.state(), State::Sleeping);
}

#[test]
fn input_before_rxen_is_dropped() {
    let mut avr = load("echo");
    avr.uart_send(b"ab");
    avr.run_for_ms(2.0);
    avr.uart_send(b"cd");
    avr.run_for_ms(5.0);
    assert!(
        avr.uart_rx_dropped() >= 1,
        "the byte at cycle 0 precedes RXEN0"
    );
    assert!(avr.uart_output_string().ends_with("cd"));
    assert!(!avr.uart_output_string().contains('a'));
}

#[test]
fn sleeping_firmware_keeps_running_and_run_until_is_exact() {
    let mut avr = load("sleepy");
    // Many short steps: each must end at (or just after) its target, never spin or jump far.
    for i in 1..=1000u64 {
        let target = i * 16_000;
        let st = avr.run_until(target);
        assert!(st.is_alive(), "{st:?}");
        let over = avr.cycle() - target;
        assert!(over <= 8, "overshoot {over} cycles at step {i}");
    }
    let t = Instant::now();
    let target = ms_to_cycles(2000.0);
    avr.run_until(target);
    let wall = t.elapsed().as_secs_f64();
    assert!(avr.cycle() - target <= 8);
    assert!(avr.uart_output_string().ends_with("tick 19\n"));
    let out = avr.uart_output_string();
    let expected: String = std::iter::once("sleepy\n".to_string())
        .chain((1..=9).map(|i| format!("tick {i}\n")))
        .collect();
    assert!(out.starts_with(&expected), "{out:?}");
    // "tick 5" is printed right after the 500th 1 ms interrupt.
    let tx = avr.uart_output();
    let pos = out.find("tick 5").unwrap();
    let ms = tx[pos].ms();
    assert!((500.0..500.2).contains(&ms), "tick 5 at {ms} ms");
    println!(
        "sleeping firmware: {:.0} simulated MHz ({} cycles in {:.4} s)",
        (target - 16_000_000) as f64 / wall / 1e6,
        target - 16_000_000,
        wall
    );
}

#[test]
fn eeprom_preload_is_seen_and_writes_read_back() {
    let mut avr = load("eeprom");
    assert_eq!(avr.eeprom_size(), 1024);
    avr.eeprom_write(0, &[1, 2, 3, 4, 0x7e, 0xa0, 0xff, 0])
        .unwrap();
    assert!(avr.eeprom_write(1020, &[0; 5]).is_err());
    assert!(avr.eeprom_read(1024, 1).is_err());
    let st = avr.run_for_ms(100.0);
    assert_eq!(st, State::Done, "sleep with interrupts off ends the run");
    assert_eq!(
        avr.uart_output_string(),
        "ee: 01 02 03 04 7e a0 ff 00\ndone\n"
    );
    let written = avr.eeprom_read(32, 16).unwrap();
    let expected: Vec<u8> = (0..16u8).map(|i| 3 * i + 1).collect();
    assert_eq!(written, expected);
    assert_eq!(
        avr.eeprom_read(48, 4).unwrap(),
        vec![0xff; 4],
        "erased EEPROM"
    );
    // A stopped core stays put.
    let c = avr.cycle();
    assert_eq!(avr.run_for_ms(10.0), State::Done);
    assert_eq!(avr.cycle(), c);
}

/// Runs the recursion fixture `depth` levels deep; returns (painted peak, RAMEND - lowest SP).
fn stack_run(depth: u8) -> (usize, usize, Avr) {
    let mut avr = load("stack");
    avr.eeprom_write(0, &[depth]).unwrap();
    avr.run_for_ms(20.0);
    let addr = avr.data_symbol("min_sp").expect("min_sp symbol");
    let d = avr.read_data(addr, 2).unwrap();
    let sp = u16::from_le_bytes([d[0], d[1]]) as usize;
    assert!(avr.uart_output_string().starts_with(&format!("sp {sp} ")));
    let peak = avr.stack_peak().expect("painted");
    (peak, avr.ramend() - sp, avr)
}

#[test]
fn stack_peak_matches_the_deepest_stack_pointer() {
    let mut peaks = Vec::new();
    for depth in [0u8, 10, 20] {
        let (peak, by_sp, _) = stack_run(depth);
        assert!(
            peak >= by_sp && peak <= by_sp + 4,
            "depth {depth}: painted peak {peak}, RAMEND - min SP {by_sp}"
        );
        peaks.push(peak);
    }
    // Ten more levels cost ten frames (the leaf differs a little from the inner levels).
    let ten = peaks[2] - peaks[1];
    assert_eq!(ten % 10, 0, "{peaks:?}");
    assert!(
        ten / 10 >= 16 + 2,
        "a level holds 16 bytes and a return address"
    );
    assert!((peaks[1] - peaks[0]).abs_diff(ten) <= 12, "{peaks:?}");

    let (_, _, mut avr) = stack_run(3);
    assert_eq!(avr.ramend(), 0x8ff);
    let end = avr.static_data_end().unwrap();
    assert!(end > 0x100 && end < 0x200, "static data ends at {end:#x}");
    assert_eq!(avr.static_data_size(), Some(end - 0x100));
    // SRAM write: the firmware spins until `mailbox` is non-zero.
    let mailbox = avr.data_symbol("mailbox").unwrap();
    avr.write_data(mailbox, &[42]).unwrap();
    avr.run_for_ms(5.0);
    assert!(
        avr.uart_output_string().ends_with("mailbox 42\n"),
        "{}",
        avr.uart_output_string()
    );
    assert!(avr.write_data(0x900, &[0]).is_err());
}

#[test]
fn watchdog_reset_keeps_the_cycle_count_monotonic() {
    let mut avr = load("wdt");
    avr.run_for_ms(100.0);
    assert!(avr.cycle() >= ms_to_cycles(100.0));
    let out = avr.uart_output_string();
    let boots = out.matches("boot\n").count();
    // WDTO_15MS: a reset about every 16.8 ms → 6 boots in 100 ms.
    assert_eq!(boots, 6, "{out:?}");
    let tx = avr.uart_output();
    assert!(tx.windows(2).all(|w| w[0].cycle < w[1].cycle));
    assert!(tx.last().unwrap().ms() > 80.0);
}

/// Echo + sleepy, step by step, returning everything observable.
type Trace = Vec<(u64, u8)>;

fn scenario(text: &[u8]) -> (Trace, Trace) {
    let mut echo = load("echo");
    let mut sleepy = load("sleepy");
    echo.run_for_ms(1.0);
    echo.uart_send(text);
    for step in 1..=300u64 {
        let target = step * ms_to_cycles(1.0);
        echo.run_until(target);
        sleepy.run_until(target);
    }
    let e = echo
        .uart_output()
        .iter()
        .map(|b| (b.cycle, b.byte))
        .collect();
    let s = sleepy
        .uart_output()
        .iter()
        .map(|b| (b.cycle, b.byte))
        .collect();
    (e, s)
}

#[test]
fn two_instances_run_independently_in_one_thread() {
    let (e, s) = scenario(b"one two");
    let text: Vec<u8> = e.iter().map(|x| x.1).collect();
    assert_eq!(text, b"one two");
    let s_text: Vec<u8> = s.iter().map(|x| x.1).collect();
    assert_eq!(s_text, b"sleepy\ntick 1\ntick 2\n");
}

#[test]
fn instances_are_send_and_deterministic_across_threads() {
    fn assert_send<T: Send>() {}
    assert_send::<Avr>();
    let reference_a = scenario(b"alpha");
    let reference_b = scenario(b"bravo!");
    let ta = std::thread::spawn(|| scenario(b"alpha"));
    let tb = std::thread::spawn(|| scenario(b"bravo!"));
    // An Avr made on one thread and run on another.
    let mut moved = load("echo");
    moved.run_for_ms(1.0);
    let tm = std::thread::spawn(move || {
        moved.uart_send(b"xyz");
        moved.run_for_ms(5.0);
        moved.uart_output_string()
    });
    assert_eq!(ta.join().unwrap(), reference_a);
    assert_eq!(tb.join().unwrap(), reference_b);
    assert_eq!(tm.join().unwrap(), "xyz");
}

#[test]
fn simulation_speed_busy_loop() {
    // The stack fixture spins on `mailbox` (an LDS/CPSE loop) with no interrupts: the worst case.
    let (_, _, mut avr) = stack_run(0);
    let t = Instant::now();
    let start = avr.cycle();
    avr.run_for_ms(2000.0);
    let wall = t.elapsed().as_secs_f64();
    let mhz = (avr.cycle() - start) as f64 / wall / 1e6;
    println!(
        "busy loop: {mhz:.1} simulated MHz per thread ({:.1}x real time){}",
        mhz / 16.0,
        if cfg!(debug_assertions) {
            " [debug build of the harness; simavr itself is built optimised]"
        } else {
            ""
        }
    );
    assert_eq!(avr.state(), State::Running);
}

#[test]
fn flash_size_is_text_plus_data_as_avr_size_counts_it() {
    let elf = common::fixture("stack");
    let out = std::process::Command::new("avr-size")
        .arg("-A")
        .arg(&elf)
        .output()
        .expect("run avr-size (binutils-avr)");
    let table = String::from_utf8_lossy(&out.stdout);
    let section = |name: &str| -> usize {
        table
            .lines()
            .find_map(|l| {
                let mut w = l.split_whitespace();
                (w.next() == Some(name)).then(|| w.next().unwrap().parse().unwrap())
            })
            .unwrap_or(0)
    };
    let text = section(".text");
    assert!(text > 0, "{table}");
    let avr = Avr::load(&elf).unwrap();
    assert_eq!(avr.flash_size(), Some(text + section(".data")), "{table}");
}

/// The profiler charges every cycle it runs to a function, and the recursion's cost to
/// `recurse`: 20 levels cost about twice 10 levels there, and the profile runs the same program
/// as `run_until` (same output, same end cycle).
#[test]
fn profile_charges_cycles_to_their_functions() {
    let profile = |depth: u8| {
        let mut avr = load("stack");
        avr.eeprom_write(0, &[depth]).unwrap();
        let start = avr.cycle();
        let target = simavr::ms_to_cycles(5.0);
        let p = avr.profile_until(target);
        assert_eq!(p.total(), avr.cycle() - start);
        let mut plain = load("stack");
        plain.eeprom_write(0, &[depth]).unwrap();
        plain.run_until(target);
        assert_eq!(plain.uart_output_string(), avr.uart_output_string());
        assert_eq!(plain.cycle(), avr.cycle());
        let of = |name: &str| p.functions.iter().find(|f| f.0 == name).map_or(0, |f| f.1);
        (of("recurse"), of("main"))
    };
    let (r10, main10) = profile(10);
    let (r20, _) = profile(20);
    assert!(r10 > 0 && main10 > 0, "{r10} {main10}");
    let ratio = r20 as f64 / r10 as f64;
    assert!(
        (1.7..2.1).contains(&ratio),
        "recurse: {r10} vs {r20} cycles"
    );
}
