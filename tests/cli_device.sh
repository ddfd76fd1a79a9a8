#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `info --device` says which device the kernels run on; a device that runs out of memory is one
# line naming it, exit 1 (the machine's limit, not a bad input's 2), reached here through
# OCC_DEVICE_ALLOC_FAIL_AT (the N-th device allocation fails as if the device were full); a
# device too small for the scene or its frames says so before the first frame.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$exe" info --device >"$dir/device.json" || fail "info --device"
grep -q '"backend": "cpu-tbb"' "$dir/device.json" || fail "no backend: $(cat "$dir/device.json")"
"$exe" info --device "$dir/x.oss" 2>/dev/null; [ $? -eq 2 ] || fail "--device with a file did not exit 2"
"$exe" info 2>/dev/null; [ $? -eq 2 ] || fail "no file and no --device did not exit 2"
"$exe" gen plant --objects 200 -o "$dir/p.glb" >/dev/null 2>&1 && "$exe" prep "$dir/p.glb" -o "$dir/p.oss" >/dev/null 2>&1 &&
  "$exe" path walk "$dir/p.oss" --frames 5 -o "$dir/p.cam" >/dev/null 2>&1 || fail "scene"
for at in 0 5 40; do
  OCC_DEVICE_ALLOC_FAIL_AT=$at "$exe" render "$dir/p.oss" --path "$dir/p.cam" --no-display >"$dir/out" 2>"$dir/err"
  status=$?
  [ $status -eq 1 ] || fail "allocation $at failing: exit $status, $(cat "$dir/err")"
  [ "$(wc -l <"$dir/err")" -eq 1 ] || fail "allocation $at failing: not one line: $(cat "$dir/err")"
  grep -q "^error: out of device memory: CPU (host memory, TBB) could not allocate [0-9.]* MiB" "$dir/err" ||
    fail "allocation $at failing: $(cat "$dir/err")"
done
# A device too small (OCC_DEVICE_MEMORY_BYTES: it holds that many bytes) is said before the
# first frame, one line, exit 1: for the scene, or for the frames (their active arrays and
# occluder raster) once the scene and the per-object arrays are on the device.
small() {
  OCC_DEVICE_MEMORY_BYTES=$1 "$exe" render "$dir/p.oss" --path "$dir/p.cam" --no-display >"$dir/out" 2>"$dir/err"
  status=$?
  [ $status -eq 1 ] || fail "a device of $1 bytes: exit $status, $(cat "$dir/err")"
  [ "$(wc -l <"$dir/err")" -eq 1 ] || fail "a device of $1 bytes: not one line: $(cat "$dir/err")"
  [ ! -s "$dir/out" ] || fail "a device of $1 bytes: frames ran: $(head -3 "$dir/out")"
}
small 1000
grep -q "^error: CPU (host memory, TBB) has 0.0 MiB free; [0-9.]* MiB needed for the scene .*p.oss: a smaller --budget" "$dir/err" ||
  fail "scene too large: $(cat "$dir/err")"
# The scene and per-object arrays of this plant take under 3 MB here; its frames more than 1 MB.
small 4000000
grep -q "MiB needed for the frames of .*p.oss (beyond the scene and its per-object arrays: active arrays for [0-9]* vertices and [0-9]* triangles [0-9.]* MiB, occluder raster of [0-9]* triangles [0-9.]* MiB)" "$dir/err" ||
  fail "frames too large: $(cat "$dir/err")"
OCC_DEVICE_MEMORY_BYTES=100000000 "$exe" render "$dir/p.oss" --path "$dir/p.cam" --no-display >/dev/null ||
  fail "a device of 100 MB"
"$exe" render "$dir/p.oss" --path "$dir/p.cam" --no-display >/dev/null || fail "the same render without the failure"
echo ok
