#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a rendered image:
# installs the dependencies (Debian packages only), builds the engine, packages
# the add-on, installs and enables it in this user's Blender 3.4 configuration,
# and renders the default scene headless through Blender.
#
#   ./setup.sh              everything
#   ./setup.sh --no-render  stop after installing the add-on
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(pwd)
RENDER=1
[[ "${1:-}" == "--no-render" ]] && RENDER=0

step() { printf '\n== %s\n' "$*"; }

# Every dependency, and why, is listed in README.md ("Dependencies").
PACKAGES=(
  build-essential cmake pkg-config
  blender python3 python3-dev python3-numpy python3-pytest python3-matplotlib
  pybind11-dev libtbb-dev libopenimageio-dev openimageio-tools python3-openimageio
  libtinygltf-dev nlohmann-json3-dev libstb-dev
  libgtest-dev libembree-dev libxxhash-dev
  xvfb libgl1-mesa-dri libglx-mesa0
  slurm-wlm munge
)

step "Installing Debian packages"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if (( ${#missing[@]} )); then
  $SUDO apt-get update
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
else
  echo "all ${#PACKAGES[@]} packages present"
fi

step "Building the engine (Release)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"

step "Packaging the add-on"
ZIP=$(/usr/bin/python3 packaging/build_zip.py | tail -n 1)
echo "$ZIP"

step "Installing and enabling the add-on in Blender's user configuration"
# Two processes: installing over an add-on that the user's preferences
# already load would make Blender reload its native module in place, which
# crashes it. The first copies the files without loading any add-on; the
# second starts with the user's preferences and enables the new files.
blender -b --factory-startup --python-exit-code 1 --python-expr "
import bpy
bpy.ops.preferences.addon_install(overwrite=True, filepath=r'''$ZIP''')
" 2>&1 | grep -E "Modules Installed|Error|error" || true
blender -b --python-exit-code 1 --python-expr "
import bpy
bpy.ops.preferences.addon_enable(module='coherent')
import coherent
bpy.ops.wm.save_userpref()
print('coherent add-on enabled from', coherent.__file__)
" 2>&1 | grep -E "coherent|Error|error" || true
blender -b --python-exit-code 1 --python-expr "
import addon_utils, sys
loaded, enabled = addon_utils.check('coherent')
sys.exit(0 if enabled else 1)
" >/dev/null 2>&1 || { echo "setup.sh: the add-on did not stay enabled in Blender's preferences" >&2; exit 1; }
echo "enabled: blender -b FILE.blend -E COHERENT -f 1 now renders with Coherent"

if (( RENDER )); then
  step "Rendering blend_scenes/cornell_box.blend headless"
  mkdir -p out
  blender -b blend_scenes/cornell_box.blend -E COHERENT -o "$ROOT/out/cornell_box_####" -F PNG -f 1 \
    | tee out/render.log | grep -E "Coherent|Saved|Error|WARNING" || true
  IMAGE="$ROOT/out/cornell_box_0001.png"
  [[ -s "$IMAGE" ]] || { echo "setup.sh: the render did not produce $IMAGE (see out/render.log)" >&2; exit 1; }
  echo
  echo "Rendered: $IMAGE"
fi
