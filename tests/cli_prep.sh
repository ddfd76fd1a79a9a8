#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch prep / verify / info on real models: a good file verifies; a flipped byte or a
# truncation fails with "error: FILE: section S at offset O: ..." and exit 2; a prep killed at
# any moment leaves no file behind; impossible options exit 2.
set -u
exe=$1
engine=/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$exe" prep "$engine" -o "$dir/engine.oss" 2>"$dir/log" || fail "prep engine: $(cat "$dir/log")"
grep -q "^prep: .* 115 objects, 34 progressive meshes" "$dir/log" || fail "summary: $(cat "$dir/log")"
"$exe" verify "$dir/engine.oss" | grep -q "^ok: " || fail "verify of a fresh file"
info=$("$exe" info "$dir/engine.oss") || fail "info"
for key in '"objects": 115' '"meshes": 34' '"cos":' '"boundary_vertex_share":' '"simplification_error":' '"TRIANGLES":'; do
  echo "$info" | grep -q "$key" || fail "info lacks $key"
done

size=$(stat -c %s "$dir/engine.oss")
for offset in 0 100 400 $((size / 3)) $((size / 2)) $((size - 1)); do
  cp "$dir/engine.oss" "$dir/bad.oss"
  printf '\xA5' | dd of="$dir/bad.oss" bs=1 seek="$offset" conv=notrunc status=none
  cmp -s "$dir/engine.oss" "$dir/bad.oss" || true
  "$exe" verify "$dir/bad.oss" >/dev/null 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "flip at $offset: exit $status"
  grep -q "^error: $dir/bad.oss: section [A-Z]* at offset [0-9]*: " "$dir/err" || fail "flip at $offset: $(cat "$dir/err")"
done
for length in 0 10 511 512 $((size / 2)) $((size - 1)); do
  head -c "$length" "$dir/engine.oss" >"$dir/cut.oss"
  "$exe" verify "$dir/cut.oss" >/dev/null 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "truncated to $length: exit $status"
  [ "$(wc -l <"$dir/err")" -eq 1 ] || fail "truncated to $length: $(cat "$dir/err")"
done

"$exe" gen plant --objects 3000 -o "$dir/plant.glb" 2>/dev/null || fail "gen plant"
for delay in 0.05 0.2 0.4 0.6 0.8 1.0; do
  "$exe" prep "$dir/plant.glb" -o "$dir/killed.oss" 2>/dev/null &
  pid=$!
  sleep "$delay"
  kill -9 $pid 2>/dev/null
  wait $pid 2>/dev/null
  if [ -e "$dir/killed.oss" ]; then
    "$exe" verify "$dir/killed.oss" >/dev/null || fail "a prep killed after ${delay}s left a bad file"
    rm "$dir/killed.oss"
  fi
  leftovers=$(ls "$dir" | grep -c "killed.oss.tmp" || true)
  [ "$leftovers" -eq 0 ] || fail "a prep killed after ${delay}s left a temporary file"
done

for bad in "--ct 1.5" "--ct -0.1" "--threads 100000"; do
  "$exe" prep "$engine" -o "$dir/x.oss" $bad 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "prep $bad: exit $status"
  [ -e "$dir/x.oss" ] && fail "prep $bad wrote a file"
done
"$exe" prep "$engine" -o "$dir/x.glb" 2>/dev/null && fail "prep accepted a non-.oss output"
# prep prints what info counts: the repeated-corner triangles it drops, and the points, lines and
# degenerate faces import skipped, and the materials no library defines.
models=/usr/share/assimp/models
for f in "$engine" $models/OBJ/testmixed.obj $models/STL/Spider_binary.stl $models/OBJ/spider.obj; do
  "$exe" prep "$f" -o "$dir/m.oss" 2>"$dir/log" || fail "prep $f: $(cat "$dir/log")"
  want=$("$exe" info "$f" | python3 -c '
import json, sys
s = json.load(sys.stdin)["skipped"]
parts = [f"{s[k]} {w}" for k, w in (("points", "points"), ("lines", "lines"), ("degenerate_faces", "degenerate faces"),
                                    ("unknown_materials", "unknown materials (drawn grey)")) if s[k]]
print(str(s["repeated_corner_triangles"]) + " repeated-corner triangles dropped" + ("; skipped at import: " + ", ".join(parts) if parts else "") + ")")')
  [ -n "$want" ] && grep -qF "$want" "$dir/log" || fail "prep $f says $(cat "$dir/log"), info: $want"
done
echo ok
