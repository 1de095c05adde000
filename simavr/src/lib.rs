//! Runs firmware ELFs in simavr: a safe harness over `simavr-ffi` ([`Avr`]), a scripted radio
//! for tests ([`ScriptedRadio`]), a modelled XBee ([`XBee`]), the radio medium ([`Medium`]) and
//! the multi-node emulated testbed that puts them together ([`Network`]).
//!
//! All of the project's `unsafe` code that concerns simavr is in the [`avr`] module; see
//! [`Avr`] for what the harness does about simavr's quirks (sleep, UART pacing, resets, threads).

pub mod avr;
pub mod elf;
pub mod medium;
pub mod network;
pub mod radio;
pub mod xbee;

pub use avr::{
    cycles_to_ms, ms_to_cycles, Avr, Error, Profile, State, UartByte, F_CPU, STACK_PAINT,
};
pub use medium::{Antenna, Medium, MediumConfig, NodeRadio};
pub use network::{Network, NetworkConfig, NodeId, NodeSpec, Outcome, RxRecord, TxRecord};
pub use radio::{frame_data, Match, ScriptError, ScriptedRadio, SeenFrame, TextLine, LINE_GAP_MS};
pub use xbee::{RxPacket, Transmission, XBee, XBeeConfig, XBeeCore};
