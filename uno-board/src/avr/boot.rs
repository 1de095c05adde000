//! The boot of every node role, up to the point where its state machine takes over.

use loc_proto::config::Config;
use loc_proto::line::BootLine;
use loc_proto::Role;
use xbee_api::driver::Radio;

use super::{
    bring_up_radio, load_config, reset, write_line, Board, Led, NodeRadio, SysClock, Watchdog,
};
use crate::WdtTimeout;

/// What a node's loop runs on, lent to it by [`boot`].
pub struct Node {
    /// The radio driver on USART0; the radio is up, in API mode 2 at 57600 with the node's `MY`,
    /// `ID` and `CH`.
    pub radio: NodeRadio,
    /// The LED (D13), off.
    pub led: Led,
    /// The watchdog, running with a 1 s timeout: the loop must feed it.
    pub watchdog: Watchdog,
    /// The config the node runs with: the one in EEPROM, or the built-in one.
    pub config: Config,
}

/// Boots a `role` node whose built-in config is `built_in`, then runs the node's loop `run`:
///
/// 1. takes the board ([`Board::take`]; the MCU resets if it was taken already),
/// 2. writes the boot line (`hoploc <role> boot`),
/// 3. runs the provisioning window and picks the config ([`load_config`]: EEPROM or
///    `built_in`; a config error blinks its code and waits for `hoploc provision`),
/// 4. brings the radio up with that config's settings ([`bring_up_radio`], retrying until the
///    radio answers),
/// 5. starts the watchdog (1 s),
/// 6. calls `run` with the radio, the LED, the watchdog and the config.
///
/// The node is lent to `run`, not returned: returned, it would be copied into the caller's frame
/// (the radio driver is most of it), and the stack is the sink's scarcest resource. Always
/// inlined: each firmware calls it once, with a constant role that folds into the code.
#[inline(always)]
pub fn boot(role: Role, built_in: Config, run: fn(&mut Node) -> !) -> ! {
    let Some(board) = Board::take() else { reset() };
    let Board {
        serial,
        led,
        mut eeprom,
        watchdog,
        ..
    } = board;
    // The node first, everything then done in place: a part moved after its address was taken
    // (the config by `load_config`, the radio by the bring-up) is a second copy on the stack.
    let mut node = Node {
        radio: Radio::new(serial, SysClock, xbee_api::Ap2),
        led,
        watchdog,
        config: built_in,
    };
    let serial = node.radio.serial_mut();
    write_line(serial, &BootLine::Boot { role });
    load_config(serial, &mut eeprom, &mut node.led, role, &mut node.config);
    bring_up_radio(
        &mut node.radio,
        &mut node.led,
        role,
        &loc_proto::config::radio_settings(&node.config),
    );
    node.watchdog.start(WdtTimeout::S1);
    run(&mut node)
}
