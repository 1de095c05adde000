#!/usr/bin/env bash
# Installs what hoploc needs on a Debian/Ubuntu machine, skipping what is already there:
# the AVR toolchain and simavr (Debian packages) and the pinned Rust nightly (rust-toolchain.toml).
# With --tests also what only the tests need: Chromium and a font for the live map's browser test
# (hoploc/tests/web.rs runs it headless), which a user of the demo does without.
# Run by ./demo.sh, ./test.sh (with --tests) and .ci/run.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

packages=(gcc-avr avr-libc binutils-avr avrdude simavr libsimavr-dev libelf-dev libclang-dev
  libzstd-dev zlib1g-dev pkg-config libudev-dev python3 python3-venv python3-pip python3-numpy)
if [ "${1:-}" = "--tests" ]; then
  packages+=(chromium fonts-dejavu-core)
fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "hoploc setup: installing Debian packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if ! command -v rustup >/dev/null 2>&1; then
  echo "hoploc setup: rustup is missing; install it from your distribution or rustup.rs first" >&2
  exit 1
fi
# Installs the nightly pinned in rust-toolchain.toml (with rust-src, clippy, rustfmt) if needed.
(cd "$here" && rustup toolchain install >/dev/null 2>&1 || (cd "$here" && rustup toolchain install))
