//! What every node's main loop does with its radio once it is up: tune to a testbed channel,
//! send a hoploc message, take what arrives (stamped with its arrival time), and idle until the
//! next event. The node logic itself is sans-IO in each `*-fw/src/lib.rs`.

use loc_proto::xbee_channel;

use super::{rx_frame_start_us, rx_pending, sleep_unless, NodeRadio, Serial};

/// How long a channel change may wait for the TX status of a frame still being sent, ms.
pub const TUNE_TIMEOUT_MS: u32 = 20;

/// How long a channel change waits for the radio's answer to `AT CH`, ms: the worst case the
/// guard time holds ([`loc_proto::schedule::TUNE_US`]), rounded up. A radio that has not answered
/// by then is taken to be on the new channel.
pub const TUNE_ANSWER_MS: u32 = loc_proto::schedule::TUNE_US.div_ceil(1000);

/// Switches the radio to testbed channel `n` (XBee `CH` = 0x0A + n): waits for the TX status of
/// any frame still being sent (a channel change would cut it off), then sends `ATCH` and waits
/// for the radio's answer, which comes once the new channel is in effect: a frame written
/// earlier may be lost. The slots' guard time holds the whole change at its worst
/// ([`loc_proto::schedule::GUARD_US`]). Frames that arrive while it waits are dropped (none are
/// due in a guard time).
///
/// True if the radio answered OK; false if `n` is not a testbed channel or the radio failed
/// (the UART, a TX status or an answer that never came, an error status). A `bool`, not the
/// driver's [`xbee_api::driver::Error`]: the nodes go on either way (the next phase tunes again), and a
/// `Result<(), Error>` comes back through memory on AVR.
pub fn tune(radio: &mut NodeRadio, n: u8) -> bool {
    let Some(ch) = xbee_channel(n) else {
        return false;
    };
    if radio.wait_tx_status(TUNE_TIMEOUT_MS, |_| ()).is_err() {
        return false;
    }
    radio.at_set(*b"CH", &[ch], TUNE_ANSWER_MS, |_| ()).is_ok()
}

/// Sends `payload` (an encoded hoploc message) to 16-bit address `dest` (0xFFFF: broadcast):
/// its frame id, or `None` if the UART failed or the payload is too long. (An `Option`, not the
/// driver's `Result<u8, Error>`, which comes back through memory on AVR; the nodes go on either
/// way.)
pub fn send(radio: &mut NodeRadio, dest: u16, payload: &[u8]) -> Option<u8> {
    radio.send_tx16(dest, payload).ok()
}

/// A frame from the radio, as the node logic needs it.
#[derive(Clone, Copy, Debug)]
pub enum Event<'a> {
    /// A packet received (RX16).
    Packet {
        /// The sender's 16-bit address.
        source: u16,
        /// Its signal strength, −dBm.
        rssi: u8,
        /// The RF payload.
        data: &'a [u8],
        /// Local time its RX frame began to arrive ([`rx_frame_start_us`]).
        at_us: u32,
    },
    /// The TX status of a frame sent: delivered (`true`) or not.
    TxStatus(bool),
    /// Any other frame (AT responses, modem status…), or one that could not be read.
    Other,
}

/// Takes the next frame the radio has completed, if any, and hands it to `f` as an [`Event`],
/// with the serial port beside it (a line written there goes out while the event's data is
/// still read in place in the driver's buffer). `None` when nothing more is waiting; stream
/// errors (counted by the driver) give `Some(f(Event::Other, …))` so the caller keeps draining.
pub fn poll<R>(radio: &mut NodeRadio, f: impl FnOnce(Event<'_>, &mut Serial) -> R) -> Option<R> {
    let mut f = Some(f);
    let r = radio.poll_with_serial(|raw, serial| {
        let ev = if let Some(rx) = raw.rx16() {
            Event::Packet {
                source: rx.source,
                rssi: rx.rssi.0,
                data: rx.data,
                at_us: rx_frame_start_us(),
            }
        } else if let Some((_, status)) = raw.tx_status() {
            Event::TxStatus(status == xbee_api::TxStatus::SUCCESS)
        } else {
            Event::Other
        };
        f.take().map(|f| f(ev, serial))
    })?;
    match r {
        Ok(Some(r)) => Some(r),
        _ => f.take().map(|f| f(Event::Other, radio.serial_mut())),
    }
}

/// Waits for the next event `wait_us` ahead: sleeps (idle) until an interrupt when that is more
/// than a tick away — the 1 ms tick or a received byte wakes the node — and returns at once
/// otherwise, so the last millisecond before a slot is spent polling the µs clock and the slot
/// starts on time (within the loop's few µs).
pub fn idle(wait_us: u32) {
    if wait_us > 1_000 {
        sleep_unless(rx_pending);
    }
}
