#!/usr/bin/env bash
# Regenerates the study pages from `hoploc simulate --report` (release build; ~10 s on 2 cores):
#   docs/study/README.md            the thesis study: P0, α and σ known
#   docs/study/estimated/README.md  the same with P0/α/σ fitted per trial (--params estimated)
#   docs/experiments/README.md      the thesis' experiments on the emulated testbed
#                                   (hoploc experiments --report; a few minutes: it runs the testbed)
# Each page records its own command line; the output is deterministic (same code, same bytes).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cargo build --release -q -p hoploc
hoploc=target/release/hoploc
"$hoploc" simulate --report docs/study >/dev/null
"$hoploc" simulate --params estimated --report docs/study/estimated >/dev/null
"$hoploc" experiments --report docs/experiments >/dev/null
