#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `info --device` says which device the kernels run on; a device that runs out of memory is one
# line naming it, exit 1 (the machine's limit, not a bad input's 2), reached here through
# OCC_DEVICE_ALLOC_FAIL_AT (the N-th device allocation fails as if the device were full).
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
  grep -q "^error: out of device memory: CPU (host memory, TBB) could not allocate [0-9]* MiB" "$dir/err" ||
    fail "allocation $at failing: $(cat "$dir/err")"
done
"$exe" render "$dir/p.oss" --path "$dir/p.cam" --no-display >/dev/null || fail "the same render without the failure"
echo ok
