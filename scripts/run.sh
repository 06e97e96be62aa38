#!/usr/bin/env bash
# The main job: builds palpa (optimized) and opens the app on the default scene shipped
# in assets/ (a window; press the liver with the mouse, a finger or a gamepad).
# Without a display (no DISPLAY / WAYLAND_DISPLAY) it renders the same scene offscreen
# instead (`palpa headless`), writes palpa-headless.png and prints the timings.
# Extra arguments are passed to palpa, e.g.
#   scripts/run.sh open --scene my-organ.palpa
#   scripts/run.sh bench eval --json
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh --gpu
[[ -f "$HOME/.cargo/env" ]] && source "$HOME/.cargo/env"
cargo build --release --locked -p palpa-app --bin palpa
if [[ $# -eq 0 && -z "${DISPLAY:-}" && -z "${WAYLAND_DISPLAY:-}" ]]; then
  echo "run.sh: no display found; rendering the default scene offscreen instead" >&2
  exec target/release/palpa headless --scene liver --out palpa-headless.png
fi
exec target/release/palpa "$@"
