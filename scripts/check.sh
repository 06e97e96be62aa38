#!/usr/bin/env bash
# What CI runs, plus formatting, lints and the cross-platform type checks.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/test.sh
cargo fmt --all --check
cargo clippy --locked --workspace --all-targets -- -D warnings
# Mobile targets: type-check only, and only where the target is installed (never in CI).
for t in aarch64-linux-android aarch64-apple-ios; do
  if rustup target list --installed 2>/dev/null | grep -qx "$t"; then
    cargo check --locked -p palpa-app --target "$t"
  else
    echo "check.sh: skipping $t (not installed; 'rustup target add $t' to check it)"
  fi
done
echo "check.sh: all checks passed"
