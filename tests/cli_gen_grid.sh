#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# A 2x3x4 grid of the engine imports as 24 times its objects and triangles, from a small file;
# prepared with the hierarchy, its repeated subtrees share HLODs (--hlod-share on, the default).
set -euo pipefail
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

"$exe" prep "$dir/grid.glb" -o "$dir/shared.oss" --node-triangles 512 2>&1 | tee "$dir/shared.log"
"$exe" prep "$dir/grid.glb" -o "$dir/own.oss" --node-triangles 512 --hlod-share off 2>&1 | tee "$dir/own.log"
number() { "$exe" info "$1" | sed -n "s/.*\"$2\": \([0-9]*\).*/\1/p"; }
inner=$(number "$dir/shared.oss" inner_nodes)
sharing=$(number "$dir/shared.oss" inner_nodes_sharing_an_hlod)
[ "$(number "$dir/own.oss" inner_nodes_sharing_an_hlod)" = 0 ] || { echo "FAIL: --hlod-share off shared HLODs"; exit 1; }
[ "$(number "$dir/own.oss" inner_nodes)" = "$inner" ] || { echo "FAIL: the trees differ"; exit 1; }
# 24 engines: most inner nodes lie in a copy of an engine (or of a group of them)
[ $((sharing * 4)) -gt $((inner * 3)) ] || { echo "FAIL: $sharing of $inner inner nodes share an HLOD"; exit 1; }
grep -qF "($sharing sharing a repeated subtree's HLOD)" "$dir/shared.log"
[ "$(stat -c %s "$dir/shared.oss")" -lt "$(stat -c %s "$dir/own.oss")" ] || { echo "FAIL: sharing did not shrink the file"; exit 1; }
"$exe" verify "$dir/shared.oss"
echo ok
