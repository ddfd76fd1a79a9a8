#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# gpu_compare.sh where no OpenGL context can be had (issue 35, item 1: a GPU machine with the
# compute driver but without its GL libraries): the comparison says so and goes on without
# drawing instead of failing. Here both sides are the CPU build (no GPU needed) and glvnd is
# given no EGL vendor, which is what such a machine looks like to EGL.
set -euo pipefail
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$exe" gen plant --objects 300 -o "$dir/plant.glb" >/dev/null
"$exe" prep "$dir/plant.glb" -o "$dir/plant.oss" >/dev/null
"$exe" path walk "$dir/plant.oss" --frames 12 -o "$dir/plant.cam" >/dev/null
mkdir -p "$dir/vendors"  # empty: no EGL vendor library at all
__EGL_VENDOR_LIBRARY_DIRS=$dir/vendors bash "$(dirname "$0")/gpu_compare.sh" "$exe" "$exe" "$dir/plant.oss" \
  "$dir/plant.cam" "$dir/out" | tee "$dir/log" || fail "gpu_compare.sh without OpenGL"
grep -q "NOTE: plant: .*no headless OpenGL" "$dir/log" || fail "the missing context is not named"
grep -q "compared without drawing (--no-display)" "$dir/log" || fail "the fallback is not said"
grep -q "^PASS: plant" "$dir/log" || fail "no comparison"
[ ! -e "$dir/out/plant-cpu" ] || [ -z "$(ls "$dir/out/plant-cpu")" ] || fail "pictures without a context"
# With a context (this machine's llvmpipe) the same call draws and compares pictures.
bash "$(dirname "$0")/gpu_compare.sh" "$exe" "$exe" "$dir/plant.oss" "$dir/plant.cam" "$dir/drawn" | tee "$dir/log2"
grep -q "NOTE" "$dir/log2" && fail "a fallback with a context"
grep -q "plant: 12 frames, 0 pictures differ" "$dir/log2" || fail "pictures not compared"
echo ok
