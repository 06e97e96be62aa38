#!/usr/bin/env bash
# Regenerates the default palpation scene shipped in assets/ (what `palpa` opens):
# the coarse-level P2 liver vademecum, its measured tradeoff table, then only what a
# phone needs: the surface rows, f32, the near and far fields in sixteen bits. The asset test checks that the result's recorded
# inputs (mesh hash, element, material, tool) match the current code.
# With TISSUE=1 it also rebuilds the scene's hyperelastic tissue, assets/liver-coarse.tissue,
# by `palpa tissue build --recipe shipped` (the stages below, about 17 h on 2 cores). The
# shipped file was made by those stages run one by one (`palpa lab tissue refine|band`),
# its weights rounded to halves between the fifth and sixth split stages (`palpa lab
# tissue cut --half-weights`, its bound 0.1 -> 0.107 mm), and its presses also tried
# Newton from rest before stopping (since dropped, docs/lab/tissue-measurements.md §3);
# the recipe stores halves from the start and differs only where that try would have
# found an equilibrium, which none measured did. With TISSUE=1 or RECORD=1 the shipped
# tissue's accuracy is measured and recorded in it (`palpa tissue check --record`), and
# docs/accuracy.md rewritten. NODULES=1 rebuilds the nodule table (below). Each file's hashes and commands go to assets/manifest.json.
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
tissue="palpa tissue build --level coarse --model neo-hookean --recipe shipped --out assets/liver-coarse.tissue"
if [ -n "${TISSUE:-}" ]; then
  # The shipped recipe (`palpa tissue build --recipe shipped`): every palpable vertex
  # and edge midpoint pressed to 15 mm, the worst triangles split in six stages (100,
  # 163, 260, 430, 540, 760 in all), the 190 worst of their sub-triangles split again,
  # then the band next to the fixed region: 8 380 presses, about 17 h on 2 cores by
  # the sum of its stages' times. Each stage logs its presses beside the output, so a
  # killed run goes on.
  $palpa ${tissue#palpa }
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
  # The tissue's hashes and the commands that made it.
  cmds=(--command "$tissue")
  for seed in ${SEEDS:-7 8 9 10}; do
    cmds+=(--command "palpa tissue check assets/liver-coarse.tissue --heldout 16 --seed $seed --depths 2.6,7.3,9.3,11.5,12.7,14.6 --record")
  done
  $palpa lab asset record assets/liver-coarse.tissue "${cmds[@]}"
fi
# The default scene's nodule table (find the nodule): every centre 3 mm apart within
# 30 mm of the palpable surface (the band where a nodule can be felt), about 25 min on
# 2 cores; with NODULES=1, then its accuracy against the full FE at held-out nodules
# written into it (about 15 min), and the tissue's with it against Newton (about 10 min).
if [ -n "${NODULES:-}" ]; then
  nodules="palpa nodule build --level coarse --band-depth-mm 30 --out assets/liver-coarse.nodules"
  $palpa ${nodules#palpa }
  cmds=(--command "$nodules")
  for seed in 12 13 7 8 10 11 18 19; do
    check="palpa nodule check assets/liver-coarse.nodules --level coarse --felt 12 --seed $seed --record"
    $palpa ${check#palpa } > /dev/null
    cmds+=(--command "$check")
  done
  # Past the ratios the one-pole form is fitted at, to 100.
  check="palpa nodule check assets/liver-coarse.nodules --level coarse --felt 12 --seed 9 --ratios 10,100 --record"
  $palpa ${check#palpa } > /dev/null
  cmds+=(--command "$check")
  # Radii past the largest tabulated (12 to 15 mm), and nodules past the band (deeper,
  # or beside a surface no probe presses), answered by the far field.
  for check in "--seed 14 --radii-mm 12,15" "--seed 16 --radii-mm 12,15" \
    "--seed 15 --past-band" "--seed 17 --past-band --radii-mm 8,15"; do
    check="palpa nodule check assets/liver-coarse.nodules --level coarse --felt 12 $check --record"
    $palpa ${check#palpa } > /dev/null
    cmds+=(--command "$check")
  done
  # The neo-Hookean tissue with a nodule (its force times 1 + e A, A the amplification
  # by the tissue's own press): every palpable vertex pressed to 10 mm without a nodule
  # (about 10 min on 2 cores), then checked against Newton with the nodule: the probe
  # within 20 mm of it (seeds 7, 8, 21), then right above it (20, 22).
  power="palpa nodule tissue assets/liver-coarse.nodules --tissue assets/liver-coarse.tissue"
  $palpa ${power#palpa } > /dev/null
  cmds+=(--command "$power")
  for seed in "7" "8" "20 --above" "21" "22 --above"; do
    check="palpa nodule check assets/liver-coarse.nodules --level coarse --tissue assets/liver-coarse.tissue --felt 5 --seed $seed --record"
    $palpa ${check#palpa } > /dev/null
    cmds+=(--command "$check")
  done
  $palpa lab asset record assets/liver-coarse.nodules "${cmds[@]}"
fi
echo "assets/liver-coarse.palpa written; tradeoff: $tmp/tradeoff.json"
cat "$tmp/tradeoff.json"
