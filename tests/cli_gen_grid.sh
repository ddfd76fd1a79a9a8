#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# A 2x3x4 grid of the engine imports as 24 times its objects and triangles, from a small file.
set -eu
exe=$1
engine=/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$exe" gen grid --model "$engine" --nx 2 --ny 3 --nz 4 -o "$dir/grid.glb"
info=$("$exe" info "$dir/grid.glb")
echo "$info"
echo "$info" | grep -q '"objects": 2760,'
echo "$info" | grep -q '"triangles": 2915904,'
size=$(stat -c %s "$dir/grid.glb")
engine_size=$(stat -c %s "$engine")
# instancing: 24 copies cost nodes, not geometry
[ "$size" -lt $((engine_size * 2)) ] || { echo "FAIL: grid file $size bytes, engine $engine_size"; exit 1; }
echo ok
