#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch path orbit|walk: writes one header line and one 12-number line per frame, the same
# bytes for the same options, one summary line; impossible options exit 2 and write nothing.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$exe" gen plant --objects 2000 -o "$dir/plant.glb" 2>/dev/null || fail "gen plant"
"$exe" prep "$dir/plant.glb" -o "$dir/plant.oss" 2>/dev/null || fail "prep plant"
"$exe" gen grid --nx 3 --ny 2 --nz 3 -o "$dir/grid.glb" 2>/dev/null || fail "gen grid"
"$exe" prep "$dir/grid.glb" -o "$dir/grid.oss" 2>/dev/null || fail "prep grid"

# A file of `frames` cameras: the header, then lines of 12 numbers.
check_file() {
  local file=$1 frames=$2
  [ "$(head -n 1 "$file")" = "# occswitch camera path v1: eye.x eye.y eye.z target.x target.y target.z up.x up.y up.z fovy_degrees near far" ] ||
    fail "$file: header $(head -n 1 "$file")"
  [ "$(wc -l <"$file")" -eq $((frames + 1)) ] || fail "$file: $(wc -l <"$file") lines for $frames frames"
  tail -n +2 "$file" | awk 'NF != 12 { exit 1 }' || fail "$file: a line without 12 numbers"
}

"$exe" path walk "$dir/plant.oss" --frames 200 -o "$dir/walk.cam" 2>"$dir/log" || fail "walk: $(cat "$dir/log")"
check_file "$dir/walk.cam" 200
[ "$(wc -l <"$dir/log")" -eq 1 ] || fail "walk: more than a summary line: $(cat "$dir/log")"
grep -q "^path: walk through $dir/plant.oss -> $dir/walk.cam: 200 cameras, path length [0-9.e+]* scene units, eye height 1.7 (floor at y = 0" \
  "$dir/log" || fail "walk summary: $(cat "$dir/log")"
# every eye at floor + 1.7, looking level
tail -n +2 "$dir/walk.cam" | awk '$2 != "1.70000005" || $5 != $2 { exit 1 }' || fail "walk: an eye off eye height"

"$exe" path walk "$dir/plant.oss" --frames 200 -o "$dir/again.cam" 2>/dev/null || fail "walk again"
cmp -s "$dir/walk.cam" "$dir/again.cam" || fail "walk: same options, different bytes"
"$exe" path walk "$dir/plant.oss" --frames 200 --seed 2 -o "$dir/seed2.cam" 2>/dev/null || fail "walk --seed 2"
cmp -s "$dir/walk.cam" "$dir/seed2.cam" && fail "walk: another seed, same path"
"$exe" path walk "$dir/plant.oss" --frames 200 --avoid triangles -o "$dir/tri.cam" 2>"$dir/log" || fail "walk --avoid triangles: $(cat "$dir/log")"
check_file "$dir/tri.cam" 200

"$exe" path walk "$dir/grid.oss" --frames 50 -o "$dir/grid.cam" 2>"$dir/log" || fail "walk grid: $(cat "$dir/log")"
check_file "$dir/grid.cam" 50
grep -q "eye height .* (no floors" "$dir/log" || fail "walk grid summary: $(cat "$dir/log")"

"$exe" path orbit "$dir/plant.oss" --frames 1 -o "$dir/one.cam" 2>/dev/null || fail "orbit of 1 frame"
check_file "$dir/one.cam" 1
"$exe" path orbit "$dir/grid.oss" -o "$dir/orbit.cam" 2>"$dir/log" || fail "orbit: $(cat "$dir/log")"
check_file "$dir/orbit.cam" 300
grep -q "^path: orbit of $dir/grid.oss -> $dir/orbit.cam: 300 cameras, path length" "$dir/log" || fail "orbit summary: $(cat "$dir/log")"
# a full turn: the first and the last eye are one step apart, not half a circle
awk 'NR == 2 { x = $1; z = $3 } END { d = sqrt(($1 - x)^2 + ($3 - z)^2); if (d > 100) exit 1 }' "$dir/orbit.cam" ||
  fail "orbit: does not close"

ls "$dir" | grep -q "\.tmp\." && fail "a temporary file was left behind"

for bad in "walk --frames 0" "walk --frames -1" "walk --frames 10000001" "walk --frames x" "walk --avoid walls" \
           "orbit --seed 3" "orbit --frames 0"; do
  "$exe" path ${bad%% *} "$dir/plant.oss" ${bad#* } -o "$dir/bad.cam" 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "path $bad: exit $status"
  [ "$(wc -l <"$dir/err")" -eq 1 ] || fail "path $bad: $(cat "$dir/err")"
  [ -e "$dir/bad.cam" ] && fail "path $bad wrote a file"
done
"$exe" path walk "$dir/plant.oss" -o "$dir/bad.txt" 2>/dev/null; [ $? -eq 2 ] || fail "accepted a non-.cam output"
"$exe" path walk "$dir/plant.oss" -o "$dir/no/such/bad.cam" 2>/dev/null; [ $? -eq 2 ] || fail "accepted a missing folder"
"$exe" path walk "$dir/missing.oss" -o "$dir/bad.cam" 2>/dev/null; [ $? -eq 2 ] || fail "accepted a missing scene"
# A model file is prepared into MODEL.oss first; a file that is neither is refused.
"$exe" path orbit "$dir/plant.glb" --frames 4 -o "$dir/model.cam" 2>"$dir/err" || fail "path of a model file: $(cat "$dir/err")"
[ -s "$dir/plant.glb.oss" ] && [ "$(grep -vc '^#' "$dir/model.cam")" -eq 4 ] || fail "no scene prepared or no cameras"
printf 'not a model\n' >"$dir/notes.txt"
"$exe" path orbit "$dir/notes.txt" -o "$dir/bad.cam" 2>"$dir/err"; [ $? -eq 2 ] || fail "accepted a .txt as a scene"
grep -q "^error: $dir/notes.txt: " "$dir/err" || fail "txt scene: $(cat "$dir/err")"
"$exe" path 2>/dev/null; [ $? -eq 2 ] || fail "path without orbit or walk"
[ -e "$dir/bad.cam" ] && fail "a failed command wrote a file"

"$exe" path --help | grep -q "orbit" || fail "path --help"
"$exe" path walk --help | grep -q -- "--seed" || fail "path walk --help"
"$exe" path orbit --help | grep -q -- "--frames" || fail "path orbit --help"
echo ok
