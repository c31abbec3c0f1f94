#!/usr/bin/env bash
# Speed of two builds side by side, for changes that must not slow anything:
# coherent-bench (single-ray traversal) and render-bench speed (whole
# renders, SPT/CPT/ICPT x single/packets, 0-4 bounces), old and new
# alternated in one loop so machine load hits both alike.
#
#   bench/compare_builds.sh OLD_BIN_DIR NEW_BIN_DIR [REPEATS] > runs.txt
#   /usr/bin/python3 bench/compare_builds.py runs.txt     # markdown table of new/old
#
# Scenes: the repo's generated Cornell box and ../shared/scenes/stanford_bunny.glb.
set -euo pipefail
old=$1 new=$2 repeats=${3:-5}
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 "$root/tests/fixtures/make_gltf.py" "$work" >/dev/null
bunny="$root/../shared/scenes/stanford_bunny.glb"
for rep in $(seq "$repeats"); do
  for v in old new; do
    bin=$old; [[ $v == new ]] && bin=$new
    for scene in "$work/cornell_box.glb" "$bunny"; do
      "$bin/render-bench" speed "$scene" --res 128 128 --spp 8 --runs 1 2>/dev/null | grep -E "^[a-z_]+,[0-9]" | sed "s/^/$v,$rep,/"
    done
    "$bin/coherent-bench" "$bunny" --json --runs 3 2>/dev/null | grep '"coherent"' | sed "s/^/$v|$rep|/"
    echo "[$rep/$repeats] $v" >&2
  done
done
