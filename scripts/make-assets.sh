#!/usr/bin/env bash
# Regenerates the default palpation scene shipped in assets/ (what `palpa` opens):
# the coarse-level P2 liver vademecum, its measured tradeoff table, then only what a
# phone needs: the surface rows, f32, the near and far fields in sixteen bits. The asset test checks that the result's recorded
# inputs (mesh hash, element, material, tool) match the current code.
# With TISSUE=1 it also rebuilds the scene's hyperelastic tissue, assets/liver-coarse.tissue:
# neo-Hookean, every palpable vertex and edge midpoint pressed to 15 mm (2 147 presses, 2-6 h
# on 2 cores), kept in target/assets/liver-coarse-base.tissue, then split in the stages of
# STAGES, each that many worst triangles in all (default "100 163 260 430 540 760": 730
# presses, about 4 h, then 441 more, about 1 h 15 min, then 627 more, about 1 h, then
# 1 002 more, about 1 h 25 min, then 690 more, about 45 min, then 1 326 more, about
# 1 h 10 min), each stage going on from the last one's file. The shipped file's weights
# were rounded to halves between the fifth and sixth stages (`palpa lab tissue cut
# --half-weights`, its bound 0.1 → 0.107 mm); a rebuild stores halves from the start,
# within 0.1 mm. Then the SUB worst of their sub-triangles are split again (the second
# level, docs/methods.md §2e), and last the band next to the fixed region is pressed (25
# edge midpoints, about 13 min). Each step
# logs its presses beside its output, so a killed run, run again, goes on from the last
# finished press. With TISSUE=1 or RECORD=1 the shipped tissue's accuracy is measured
# and recorded in it (`palpa tissue check --record`), and docs/accuracy.md rewritten.
# The shipped file's presses also tried Newton from rest before stopping
# (since dropped, docs/lab/tissue-measurements.md §3): a rebuild differs only where that try
# would have found an equilibrium, which none measured did.
set -euo pipefail
cd "$(dirname "$0")/.."
# MODES overrides the nodal build's global modes; PALPA a palpa binary already built.
modes=()
[ -n "${MODES:-}" ] && modes=(--modes "$MODES")
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
palpa="${PALPA:-}"
if [ -z "$palpa" ]; then
  cargo build --release --locked -q -p palpa-app --bin palpa
  palpa=target/release/palpa
fi
mkdir -p target/assets
offline="palpa offline liver --level coarse --element p2 ${modes[*]} --out target/assets/liver-coarse-full.palpa"
tradeoff="palpa tradeoff target/assets/liver-coarse-full.palpa --json"
export="palpa export-scene target/assets/liver-coarse-full.palpa --surface-only --precision f32 --out assets/liver-coarse.palpa"
$palpa ${offline#palpa }
$palpa ${tradeoff#palpa } > "$tmp/tradeoff.json"
$palpa ${export#palpa }
# Its hashes and the commands that made it, in assets/manifest.json.
$palpa lab asset record assets/liver-coarse.palpa \
  --command "$offline" --command "$tradeoff" --command "$export"
if [ -n "${TISSUE:-}" ]; then
  mkdir -p target/assets
  $palpa tissue build --level coarse --model neo-hookean --depth-max-mm 15 --no-refine \
    --out target/assets/liver-coarse-base.tissue
  from=target/assets/liver-coarse-base.tissue
  for k in ${STAGES:-100 163 260 430 540 760}; do
    $palpa lab tissue refine "$from" --triangles "$k" --out "target/assets/liver-coarse-$k.tissue"
    from="target/assets/liver-coarse-$k.tissue"
  done
  # The second level: the SUB worst sub-triangles of those split again (default 190:
  # 1 392 presses, about 4 h; its file, tissue format 12, was 7.98 MB).
  $palpa lab tissue refine "$from" --sub-triangles "${SUB:-190}" \
    --out "target/assets/liver-coarse-sub${SUB:-190}.tissue"
  from="target/assets/liver-coarse-sub${SUB:-190}.tissue"
  # The band next to the fixed region, last (25 presses; format 13, 7.91 MB: with the
  # scene 11.4 MB of the 20 MB phone budget).
  $palpa lab tissue band "$from" --out target/assets/liver-coarse-band.tissue
  from=target/assets/liver-coarse-band.tissue
  cp "$from" assets/liver-coarse.tissue
fi
# What the shipped tissue is measured to be worth, written into it: seeded held-out
# points against the full nonlinear FE (about 15 minutes a seed on 2 cores).
# SEEDS overrides the draws (default "7 8 9 10").
if [ -n "${TISSUE:-}${RECORD:-}" ]; then
  for seed in ${SEEDS:-7 8 9 10}; do
    $palpa tissue check assets/liver-coarse.tissue --heldout 16 --seed "$seed" \
      --depths 2.6,7.3,9.3,11.5,12.7,14.6 --record > /dev/null
  done
  $palpa lab accuracy --write docs/accuracy.md
  # The tissue's hashes and the commands that made it (this script's, in order).
  cmds=(--command "palpa tissue build --level coarse --model neo-hookean --depth-max-mm 15 --no-refine --out target/assets/liver-coarse-base.tissue")
  from=target/assets/liver-coarse-base.tissue
  for k in ${STAGES:-100 163 260 430 540 760}; do
    cmds+=(--command "palpa lab tissue refine $from --triangles $k --out target/assets/liver-coarse-$k.tissue")
    from="target/assets/liver-coarse-$k.tissue"
  done
  cmds+=(--command "palpa lab tissue refine $from --sub-triangles ${SUB:-190} --out target/assets/liver-coarse-sub${SUB:-190}.tissue")
  cmds+=(--command "palpa lab tissue band target/assets/liver-coarse-sub${SUB:-190}.tissue --out target/assets/liver-coarse-band.tissue")
  cmds+=(--command "cp target/assets/liver-coarse-band.tissue assets/liver-coarse.tissue")
  for seed in ${SEEDS:-7 8 9 10}; do
    cmds+=(--command "palpa tissue check assets/liver-coarse.tissue --heldout 16 --seed $seed --depths 2.6,7.3,9.3,11.5,12.7,14.6 --record")
  done
  $palpa lab asset record assets/liver-coarse.tissue "${cmds[@]}"
fi
echo "assets/liver-coarse.palpa written; tradeoff: $tmp/tradeoff.json"
cat "$tmp/tradeoff.json"
