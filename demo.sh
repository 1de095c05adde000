#!/usr/bin/env bash
# The main job: the hoploc network of real firmware running in simavr with modelled XBee radios.
# Installs what is missing, builds the firmware, then runs `hoploc demo` (arguments pass through,
# e.g. ./demo.sh --seconds 10).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
bash scripts/setup.sh
cargo fw
cargo run --release -q -p hoploc -- demo "$@"
