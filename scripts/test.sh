#!/usr/bin/env bash
# Every test of the workspace: unit, integration, property, doc tests, and each
# benchmark run once in test mode. This is exactly what CI runs (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
[[ -f "$HOME/.cargo/env" ]] && source "$HOME/.cargo/env"
export CARGO_TERM_COLOR=never
cargo test --locked --workspace --all-targets
cargo test --locked --workspace --doc
