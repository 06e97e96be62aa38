#!/usr/bin/env bash
# Regenerates the second organ shipped in assets/: the kidney surface (made here, as a
# segmentation export would give it: cm, y up, z anterior) and its coarse palpation
# scene. The asset test rebuilds the mesh from the surface with these same arguments
# and checks that the scene's recorded inputs match.
set -euo pipefail
cd "$(dirname "$0")/.."
palpa="${PALPA:-}"
if [ -z "$palpa" ]; then
  cargo build --release --locked -q -p palpa-app --bin palpa
  palpa=target/release/palpa
fi
shape="palpa scene shape kidney --out assets/kidney/kidney.obj"
# Attached on its posterior face (it lies on the posterior abdominal wall), pressed
# from the front and sides.
build="palpa scene build --surface assets/kidney/kidney.obj --units cm --up y --anterior z \
--fixed normal:posterior:50 --palpable normal:anterior:85 --level coarse \
--out assets/kidney/kidney-coarse.palpa --json"
# Each file's hashes and the command that made it go to assets/manifest.json; a test
# runs these commands again and compares.
$palpa ${shape#palpa }
$palpa lab asset record assets/kidney/kidney.obj --command "$shape"
$palpa ${build#palpa }
$palpa lab asset record assets/kidney/kidney-coarse.palpa --command "$shape" --command "$build"
