#!/usr/bin/env bash
# Fuzzes a reader for a while (default 60 s): scripts/fuzz.sh [SECONDS] [TARGET]
# TARGET: load_model (the meta-model loader, default), network_file (SBML and TOML),
# surface_file (OBJ, STL, PLY) or regions (region files and selectors).
# Needs cargo-fuzz (installed here if missing). On a stable toolchain cargo-fuzz's
# sanitizer flags need RUSTC_BOOTSTRAP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-60}"
target="${2:-load_model}"
command -v cargo-fuzz >/dev/null 2>&1 || cargo install --locked cargo-fuzz
mkdir -p fuzz/corpus/load_model fuzz/corpus/network_file fuzz/corpus/surface_file fuzz/corpus/regions
cp tests/data/dsmts/*/*-sbml-l3v1.xml assets/networks/*.toml fuzz/corpus/network_file/
cargo run --release --locked -q -p palpa-app --bin palpa -- synth --rows 30 --modes 4 --out fuzz/corpus/load_model/seed-f64.palpa
for f in sphere.obj sphere.stl sphere.ply; do
  cargo run --release --locked -q -p palpa-app --bin palpa -- scene shape sphere --subdivisions 1 --out "fuzz/corpus/surface_file/$f" >/dev/null
done
printf 'version = 1\nmatch_radius_mm = 5.0\nfixed_selectors = ["normal:posterior:45 & !ball:0,0,0:10"]\nfixed_points = [[1.0, 2.0, 3.0]]\n' > fuzz/corpus/regions/seed.toml
cargo run --release --locked -q -p palpa-app --bin palpa -- synth --rows 12 --modes 3 --precision f32 --out fuzz/corpus/load_model/seed-f32.palpa
cd fuzz
RUSTC_BOOTSTRAP=1 cargo fuzz run "$target" -- -max_total_time="$secs" -rss_limit_mb=2048
