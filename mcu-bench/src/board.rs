//! What the `board-check` firmware does, shared by the firmware and the host test
//! (`tests/tests/board.rs`): uno-board's LED through embedded-hal's pin traits, its `Delay`
//! through `DelayNs`, and its UART receive ring, each step announced on the UART so that the
//! test can tell, from the cycle simavr stamps on each byte the firmware writes, what the
//! firmware did when.
//!
//! 1. **LED**: each of [`LED_STEPS`] through `OutputPin`/`StatefulOutputPin`, then the two bytes
//!    `'0' + is_set_high`, `'0' + is_set_low`, each waited out on the line (the test samples
//!    PB5 as they are written), then 1 ms.
//! 2. **Delays**: `'D'`, then `'<'` and `'>'` without a delay between them (the pair's own
//!    cost), then for each of [`DELAYS`] `'<'`, the delay, `'>'`; each byte waited out on the
//!    line.
//! 3. **Full ring**: `'R'` (waited out), then [`FULL_WAIT_MS`] without reading while the test sends
//!    [`FULL_SENT`] bytes, then every byte the ring holds, echoed, and `'\n'`.
//! 4. **Stream**: the `now_us` of the moment, 4 bytes little-endian, and `'S'`; then every byte read
//!    echoed until [`STREAM_LEN`] bytes or [`STREAM_TIMEOUT_MS`]; then `rx_frame_start_us()`, 4
//!    bytes little-endian (when the last 0x7E the test sent arrived).
//! 5. `end\n`, and the MCU stops.

/// What a step of the LED phase does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LedStep {
    /// `OutputPin::set_high`.
    High,
    /// `OutputPin::set_low`.
    Low,
    /// `StatefulOutputPin::toggle`.
    Toggle,
}

/// The LED phase's steps; the LED starts off.
pub const LED_STEPS: [LedStep; 6] = [
    LedStep::High,
    LedStep::High,
    LedStep::Toggle,
    LedStep::Toggle,
    LedStep::Low,
    LedStep::Toggle,
];

/// Whether the LED is on after each of [`LED_STEPS`], as the steps mean it.
pub const fn led_states() -> [bool; LED_STEPS.len()] {
    let mut states = [false; LED_STEPS.len()];
    let mut on = false;
    let mut i = 0;
    while i < LED_STEPS.len() {
        on = match LED_STEPS[i] {
            LedStep::High => true,
            LedStep::Low => false,
            LedStep::Toggle => !on,
        };
        states[i] = on;
        i += 1;
    }
    states
}

/// Which `DelayNs` method a delay case calls.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DelayKind {
    /// `delay_ms`.
    Ms,
    /// `delay_us`.
    Us,
    /// `delay_ns`.
    Ns,
}

/// The delay phase's cases, in order: the method and its argument.
pub const DELAYS: [(DelayKind, u32); 20] = [
    (DelayKind::Ms, 0),
    (DelayKind::Ms, 1),
    (DelayKind::Ms, 2),
    (DelayKind::Ms, 10),
    (DelayKind::Ms, 250),
    (DelayKind::Ms, 1500),
    (DelayKind::Ms, 65_534),
    (DelayKind::Ms, 66_000),
    (DelayKind::Us, 0),
    (DelayKind::Us, 1),
    (DelayKind::Us, 10),
    (DelayKind::Us, 100),
    (DelayKind::Us, 999),
    (DelayKind::Us, 4_321),
    (DelayKind::Us, 70_000),
    (DelayKind::Ns, 1),
    (DelayKind::Ns, 999),
    (DelayKind::Ns, 1_001),
    (DelayKind::Ns, 250_000),
    (DelayKind::Ns, 4_000_000),
];

/// How long the full-ring phase does not read, ms.
pub const FULL_WAIT_MS: u32 = 100;
/// Bytes the test sends in the full-ring phase: more than the ring holds.
pub const FULL_SENT: usize = 200;
/// Bytes the stream phase reads and echoes.
pub const STREAM_LEN: usize = 300;
/// The stream phase's limit, ms.
pub const STREAM_TIMEOUT_MS: u32 = 2_000;
