#!/usr/bin/env bash
# Builds (incrementally) and runs every test that needs nothing beside the
# clone: the native GoogleTest suite, the CLI tests and the Blender add-on
# tests, all through CTest, as many at once as there are cores. Tests
# labelled `shared` (they check the public scenes in ../shared/scenes) are
# left out; run them with
#   ctest --test-dir build -L shared --output-on-failure
# Extra arguments go to ctest (e.g. -R blender-viewport).
set -euo pipefail
cd "$(dirname "$0")"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
# One test per core: the suite's time limits allow for the neighbour (tests/CMakeLists.txt).
ctest --test-dir build --output-on-failure -j"$(nproc)" -LE shared "$@"
