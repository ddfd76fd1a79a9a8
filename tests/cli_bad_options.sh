#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Impossible options exit 2 with one "error:" line and leave no output file behind.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
expect_error() {
  "$exe" "$@" >"$dir/out" 2>"$dir/err"
  local status=$?
  [ "$status" -eq 2 ] || { echo "FAIL: '$*' exited $status"; cat "$dir/err"; exit 1; }
  grep -q "^error: " "$dir/err" || { echo "FAIL: '$*' printed no error line"; cat "$dir/err"; exit 1; }
  [ "$(ls "$dir" | grep -v -x -e out -e err | wc -l)" -eq 0 ] || { echo "FAIL: '$*' left files: $(ls "$dir")"; exit 1; }
}
expect_error gen plant --objects 0 -o "$dir/p.glb"
expect_error gen plant --objects -5 -o "$dir/p.glb"
expect_error gen plant --objects 10 -o "$dir/no/such/folder/p.glb"
expect_error gen plant --objects 10 -o "$dir/p.txt"
expect_error gen grid --nx 0 -o "$dir/g.glb"
expect_error gen grid --nx 2 --spacing -1 -o "$dir/g.glb"
expect_error gen grid --model "$dir/missing.glb" -o "$dir/g.glb"
expect_error info
expect_error info "$dir/missing.glb"
expect_error frobnicate
echo ok
