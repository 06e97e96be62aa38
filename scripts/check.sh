#!/usr/bin/env bash
# What CI runs, plus formatting, lints and the cross-platform type checks.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/test.sh
cargo fmt --all --check
cargo clippy --locked --workspace --all-targets -- -D warnings
# Licences, duplicate versions and sources (deny.toml); advisories need the RustSec
# database from GitHub, so they are checked only with PALPA_ADVISORIES=1.
if cargo deny --version >/dev/null 2>&1; then
  cargo deny check licenses bans sources
  if [ "${PALPA_ADVISORIES:-0}" = 1 ]; then cargo deny check advisories; fi
else
  echo "check.sh: skipping cargo deny (not installed; 'cargo install cargo-deny --locked')"
fi
# Every reader fuzzed briefly (cargo-fuzz; PALPA_FUZZ_SECONDS each, 0 to skip).
if [ "${PALPA_FUZZ_SECONDS:-10}" != 0 ]; then
  scripts/fuzz.sh --ci "${PALPA_FUZZ_SECONDS:-10}"
fi
# Mobile targets: the app library built without the CLI, as a static library per
# installed target (aarch64-linux-android, aarch64-apple-ios, aarch64-apple-ios-sim),
# with sizes; targets not installed are skipped with the command that installs them.
scripts/mobile-libs.sh
echo "check.sh: all checks passed"
