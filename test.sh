#!/usr/bin/env bash
# Runs the whole hoploc test suite (host tests, codec interop with Digi's library, firmware in
# simavr, the live map in headless Chromium). Installs what is missing first.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
bash scripts/setup.sh --tests
# The firmware must build for the Uno; simavr-based tests run the ELFs (the node firmwares, and
# the MCU estimate benchmark's for tests/tests/mcu_bench.rs).
cargo fw
# They link with --relax: check that the linker changed only calls and jumps (see the script).
scripts/relax-check
cargo fw-bench
cargo test --workspace "$@"
# xbee-api's opt-in serial adapters: the workspace build leaves their features off.
cargo test -p xbee-api --all-features --test adapter_eh02 --test adapter_io --examples "$@"
