#!/usr/bin/env bash
# Fuzzes the readers with cargo-fuzz (libFuzzer).
#   scripts/fuzz.sh [SECONDS] [TARGET]   one target for a while (default 60 s, load_model)
#   scripts/fuzz.sh --ci [SECONDS]       every target briefly (default 10 s each), with
#                                        the number of inputs each ran
# TARGETS: load_model (meta-model files of every kind), network_file (SBML and TOML),
# surface_file (OBJ, STL, PLY), regions (region files and selectors), paths (headless
# probe and coordinate paths).
# Needs cargo-fuzz (installed here if missing). On a stable toolchain cargo-fuzz's
# sanitizer flags need RUSTC_BOOTSTRAP=1. A crash is saved under fuzz/artifacts/TARGET/.
set -euo pipefail
cd "$(dirname "$0")/.."
targets=(load_model network_file surface_file regions paths)
if [ "${1:-}" = "--ci" ]; then
  ci=1
  secs="${2:-10}"
else
  ci=0
  secs="${1:-60}"
  targets=("${2:-load_model}")
fi
command -v cargo-fuzz >/dev/null 2>&1 || cargo install --locked cargo-fuzz
for t in load_model network_file surface_file regions paths; do mkdir -p "fuzz/corpus/$t"; done
cp tests/data/dsmts/*/*-sbml-l3v1.xml assets/networks/*.toml fuzz/corpus/network_file/
cargo build --release --locked -q -p palpa-app --bin palpa
palpa=target/release/palpa
$palpa lab synth --rows 30 --modes 4 --out fuzz/corpus/load_model/seed-f64.palpa >/dev/null
$palpa lab synth --rows 12 --modes 3 --precision f32 --out fuzz/corpus/load_model/seed-f32.palpa >/dev/null
# Network models of each layout (short runs: small files).
seed() { "$palpa" "$@" >/dev/null 2>"$tmp_err" || { cat "$tmp_err" >&2; echo "fuzz.sh: seeding failed: palpa $*" >&2; exit 1; }; }
tmp_err="$(mktemp)"
seed cme offline toggle --t-end 2 --out fuzz/corpus/load_model/seed-tt.palpa
seed cme offline toggle --t-end 2 --keep views --out fuzz/corpus/load_model/seed-views.palpa
seed cme offline toggle --t-end 2 --solver greedy --out fuzz/corpus/load_model/seed-greedy.palpa
rm -f "$tmp_err"
for f in sphere.obj sphere.stl sphere.ply; do
  $palpa scene shape sphere --subdivisions 1 --out "fuzz/corpus/surface_file/$f" >/dev/null
done
printf 'version = 1\nmatch_radius_mm = 5.0\nfixed_selectors = ["normal:posterior:45 & !ball:0,0,0:10"]\nfixed_points = [[1.0, 2.0, 3.0]]\n' > fuzz/corpus/regions/seed.toml
printf '(normal:-y:45 | half:0,0,-20:0,0,1) & !polyline:0,0,0;10,0,0:5' > fuzz/corpus/regions/selector.txt
printf '{"keyframes": [{"t_s": 0, "at_mm": [0, 40, 0], "depth_mm": 0}, {"t_s": 2, "at_mm": [10, 40, 5], "depth_mm": 8}]}' > fuzz/corpus/paths/probe.json
printf '{"keyframes": [{"t_s": 0, "coordinates": {"t": 0}}, {"t_s": 4, "coordinates": {"t": 10, "delta": 0.02}}]}' > fuzz/corpus/paths/coordinates.json
cd fuzz
for t in "${targets[@]}"; do
  log="$(mktemp)"
  features=()
  [ "$t" = paths ] && features=(--features app)
  if ! RUSTC_BOOTSTRAP=1 cargo fuzz run "${features[@]}" "$t" -- -max_total_time="$secs" -rss_limit_mb=2048 \
      >"$log" 2>&1; then
    tail -40 "$log"
    echo "fuzz.sh: $t FAILED (the input is under fuzz/artifacts/$t/)"
    exit 1
  fi
  runs="$(grep -o 'Done [0-9]* runs' "$log" | tail -1 | grep -o '[0-9]*' || echo '?')"
  echo "fuzz.sh: $t: $runs inputs in $secs s, no crash"
  [ "$ci" = 1 ] || tail -5 "$log"
  rm -f "$log"
done
