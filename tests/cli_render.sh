#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch render --no-display runs a walk and an orbit end to end on a real scene and writes
# one CSV row per frame with the columns the issue names; impossible options exit 2.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$exe" gen plant --objects 800 -o "$dir/p.glb" 2>/dev/null || fail "gen"
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" 2>/dev/null || fail "prep"
"$exe" path walk "$dir/p.oss" --frames 30 -o "$dir/walk.cam" 2>/dev/null || fail "path walk"
"$exe" path orbit "$dir/p.oss" --frames 12 -o "$dir/orbit.cam" 2>/dev/null || fail "path orbit"
for mode in full lod oc+lod; do
  for stream in sc snc ns; do
    out=$("$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display --mode $mode --stream $stream \
          --size 256x192 --stats "$dir/s.csv") || fail "render $mode $stream"
    echo "$out" | grep -q "^render: .* 30 frames at 256x192, mode $mode, stream $stream" || fail "summary: $out"
    [ "$(wc -l <"$dir/s.csv")" -eq 31 ] || fail "$mode $stream: CSV has $(wc -l <"$dir/s.csv") lines"
  done
done
header=$(head -1 "$dir/s.csv")
for column in frame objects_in_frustum objects_occluded objects_visible aos_size active_triangles active_vertices \
              streamed_triangles streamed_vertices ms_frustum_cull ms_depth_raster ms_hzm_build ms_hzm_test \
              ms_lod_select ms_scan ms_stream_collect ms_defragment ms_reform ms_total; do
  echo "$header" | tr ',' '\n' | grep -qx "$column" || fail "CSV lacks column $column"
done
"$exe" render "$dir/p.oss" --path "$dir/orbit.cam" --no-display >/dev/null || fail "orbit"
# --summary: the run's figures as JSON, the same frames and backend the printed summary names.
out=$("$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display --summary "$dir/s.json") || fail "--summary"
python3 - "$dir/s.json" "$out" <<'PY' || fail "--summary: $(cat "$dir/s.json")"
import json, re, sys
j = json.load(open(sys.argv[1]))
m = re.search(r"^render: .*, (\d+) frames at .*, backend ([^,]+),", sys.argv[2], re.M)
assert m and j["frames"] == int(m.group(1)) and j["backend"] == m.group(2), (j, sys.argv[2])
assert j["ranks"] == 1 and j["ms_frame"] > 0 and j["objects_visible"] >= 0 and "pace" not in j
PY
"$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display --pace recorded --path-fps 600 \
  --summary "$dir/paced.json" >/dev/null || fail "--summary, paced"
python3 -c "import json,sys; p=json.load(open(sys.argv[1]))['pace']; assert p['frames_shown'] + p['poses_skipped'] == p['poses'] > 0" \
  "$dir/paced.json" || fail "--summary, paced: $(cat "$dir/paced.json")"
# A window has no summary file: refused before anything opens, and nothing written.
"$exe" render "$dir/p.oss" --summary "$dir/w.json" >/dev/null 2>"$dir/err"; status=$?
[ $status -eq 2 ] && grep -q "^error: render: --summary describes recorded runs" "$dir/err" && [ ! -e "$dir/w.json" ] ||
  fail "--summary in a window: exit $status, $(cat "$dir/err")"
"$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display --raster masked >/dev/null || fail "walk, masked raster"
# Each impossible option is named by its flag, also when the library found it out of range.
for bad in "--size 0x10" "--size big" "--mode none" "--stream fast" "--alpha 1" "--pet -1" "--budget -3" \
           "--budget 200%" "--budget many" "--lod-hysteresis 1" "--aos 100000" "--pace slow" "--path-fps 0" \
           "--link x" "--link 1:0" "--link -1" "--link 1:100:2:3" "--link 1::2" "--colours red" "--raster fast" \
           "--hierarchy maybe"; do
  "$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display $bad >/dev/null 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "render $bad: exit $status"
  [ "$(wc -l <"$dir/err")" -eq 1 ] && grep -q -- "^error: ${bad%% *}" "$dir/err" || fail "render $bad: $(cat "$dir/err")"
done
# The default budget follows the screen: one vertex per pixel, at most the scene's vertices.
"$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display --size 64x48 --stats "$dir/b.csv" >/dev/null ||
  fail "render 64x48"
python3 - "$dir/b.csv" <<'PY' || fail "default budget at 64x48"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert rows and all(int(r["budget_vertices"]) == 64 * 48 for r in rows), rows[0]["budget_vertices"]
PY
"$exe" render "$dir/p.oss" --path "$dir/walk.cam" --no-display --hierarchy off --budget 10% --stats "$dir/b.csv" >/dev/null ||
  fail "render --budget 10%"
vertices=$("$exe" info "$dir/p.oss" | python3 -c "import json,sys; print(json.load(sys.stdin)['vertices'])")
python3 - "$dir/b.csv" "$vertices" <<'PY' || fail "--budget 10% of $vertices vertices"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert all(abs(int(r["budget_vertices"]) - 0.1 * int(sys.argv[2])) <= 1 for r in rows), rows[0]["budget_vertices"]
PY
"$exe" render "$dir/p.oss" --path "$dir/missing.cam" --no-display >/dev/null 2>"$dir/err"
[ $? -eq 2 ] && grep -q "missing.cam" "$dir/err" || fail "a missing path file: $(cat "$dir/err")"
# A model file renders directly: prepared once into MODEL.oss beside it, reused while unchanged,
# prepared again when its bytes change.
cp "$dir/p.glb" "$dir/m.glb"
"$exe" render "$dir/m.glb" --path "$dir/walk.cam" --no-display >/dev/null 2>"$dir/first" || fail "render of a model file: $(cat "$dir/first")"
grep -q "preparing it into $dir/m.glb.oss" "$dir/first" || fail "no preparation: $(cat "$dir/first")"
[ -s "$dir/m.glb.oss" ] && [ -s "$dir/m.glb.oss.source" ] || fail "no cache beside the model"
"$exe" render "$dir/m.glb" --path "$dir/walk.cam" --no-display >/dev/null 2>"$dir/second" || fail "second render"
grep -q "using the prepared scene $dir/m.glb.oss" "$dir/second" || fail "cache not reused: $(cat "$dir/second")"
"$exe" gen plant --objects 300 -o "$dir/m.glb" 2>/dev/null || fail "gen"
"$exe" render "$dir/m.glb" --path "$dir/walk.cam" --no-display >/dev/null 2>"$dir/third" || fail "third render"
grep -q "preparing it into" "$dir/third" || fail "a changed model was not prepared again: $(cat "$dir/third")"
"$exe" render "$dir/missing.glb" --path "$dir/walk.cam" --no-display >/dev/null 2>"$dir/err"; status=$?
[ $status -eq 2 ] && grep -q "missing" "$dir/err" || fail "a missing model: exit $status, $(cat "$dir/err")"
echo ok
