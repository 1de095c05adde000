//! Runs firmware ELFs in simavr: harness, modelled XBee radios, radio medium, emulated testbed.
