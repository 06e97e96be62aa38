#!/usr/bin/env bash
# The main job: builds palpa (optimized) and runs it with no arguments, which opens the
# default scene from assets/ (until the app lands: the CLI overview and a short
# evaluator benchmark). Extra arguments are passed to palpa, e.g.
#   scripts/run.sh bench eval --json
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
[[ -f "$HOME/.cargo/env" ]] && source "$HOME/.cargo/env"
cargo build --release --locked -p palpa-app --bin palpa
exec target/release/palpa "$@"
