#!/usr/bin/env bash
# Builds (incrementally) and runs every test: the native GoogleTest suite, the
# CLI tests and the Blender add-on tests, all through CTest.
set -euo pipefail
cd "$(dirname "$0")"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure --timeout 1500 "$@"
