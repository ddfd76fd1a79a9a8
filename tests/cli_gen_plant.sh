#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# gen plant is deterministic (same seed, same bytes; another seed, other bytes) and its output
# imports with the requested number of objects.
set -eu
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$exe" gen plant --objects 500 --seed 7 -o "$dir/a.glb"
"$exe" gen plant --objects 500 --seed 7 -o "$dir/b.glb"
"$exe" gen plant --objects 500 --seed 8 -o "$dir/c.glb"
cmp "$dir/a.glb" "$dir/b.glb"
if cmp -s "$dir/a.glb" "$dir/c.glb"; then echo "FAIL: seeds 7 and 8 gave the same file"; exit 1; fi
"$exe" info "$dir/a.glb" | grep -q '"objects": 500,'
ls "$dir" | grep -q tmp && { echo "FAIL: temporary file left behind"; exit 1; }
echo ok
