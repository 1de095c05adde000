//! The wire contract: beacon/report messages, sink output lines, provisioning frames, node config.
#![no_std]
