#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch render --headless draws a walk through a small plant with EGL: no false culls on any
# frame against the full-detail item buffer, PSNR >= 30 dB against the full-detail picture, one
# W x H PNG per frame, debug views of the chosen frames; --mode full draws exactly the reference.
# Impossible options exit 2 with one error line; a run that fails leaves no stats file.
set -u
export TESTS_DIR; TESTS_DIR=$(cd "$(dirname "$0")" && pwd)
exe=$1
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$(cd "$(dirname "$0")" && pwd)/lsan.supp:print_suppressions=0}
# Mesa's llvmpipe driver (swrast_dri.so) leaks 240 bytes in 3 blocks and is unloaded by
# eglTerminate before LeakSanitizer looks, so the reports name "<unknown module>", which no
# suppression can match. Under AddressSanitizer this test checks memory errors, not leaks.
if ldd "$exe" 2>/dev/null | grep -q libasan; then
  export ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0
fi
dir=$(mktemp -d)
trap 'chmod -R u+w "$dir"; rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$exe" gen plant --objects 600 -o "$dir/p.glb" 2>/dev/null || fail "gen"
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" 2>/dev/null || fail "prep"
"$exe" path walk "$dir/p.oss" --frames 40 -o "$dir/walk.cam" 2>/dev/null || fail "path walk"
render() { "$exe" render "$dir/p.oss" --path "$dir/walk.cam" --size 256x192 "$@"; }

# A CSV column by name, one value per data row.
column() { awk -F, -v name="$2" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == name) c = i; next } { print $c }' "$1"; }

# A budget of 10 % of the scene's vertices (5.6 K here) would draw this small plant's ~150
# visible objects coarsely: 24 dB. 20 K vertices keeps what is seen near full detail, so that
# PSNR >= 30 dB checks the drawing, not the budget.
render --headless --exact --reference --budget 20000 --out "$dir/F" --debug-views "$dir/D" --debug-frames 0,20 \
       --stats "$dir/s.csv" >"$dir/out" 2>"$dir/err" || fail "render: $(cat "$dir/err")"
[ "$(wc -l <"$dir/s.csv")" -eq 41 ] || fail "CSV has $(wc -l <"$dir/s.csv") lines, not 41"
header=$(head -1 "$dir/s.csv")
for c in ms_draw uploaded_bytes draw_calls ms_exact exact_visible false_culls exact_occluded culling_accuracy \
         psnr_db changed_pixel_share mse perceptible_share ssim bound_p99_px bound_pixels bound_beyond_tau; do
  echo "$header" | tr ',' '\n' | grep -qx "$c" || fail "CSV lacks column $c"
done
column "$dir/s.csv" false_culls | awk '$1 != 0 { bad = 1 } END { exit bad }' || fail "false culls: $(column "$dir/s.csv" false_culls | tr '\n' ' ')"
column "$dir/s.csv" exact_visible | awk '$1 > 0 { n++ } END { exit !(n >= 30) }' || fail "exact_visible is 0 on most rows"
column "$dir/s.csv" culling_accuracy | awk '!($1 >= 0 && $1 <= 100.5) { bad = 1 } END { exit bad }' ||
  fail "culling_accuracy out of [0, 100]: $(column "$dir/s.csv" culling_accuracy | tr '\n' ' ')"
column "$dir/s.csv" psnr_db | awk '!($1 >= 30) { bad = 1 } END { exit bad }' ||
  fail "PSNR below 30 dB: $(column "$dir/s.csv" psnr_db | tr '\n' ' ')"
grep -q "^exact: 0 false culls" "$dir/out" || fail "summary: $(cat "$dir/out")"

# Frames: 40 PNGs of 256 x 192 RGB; a frame is more than the background.
[ "$(ls "$dir/F" | wc -l)" -eq 40 ] || fail "$(ls "$dir/F" | wc -l) files in --out, not 40"
python3 - "$dir/F" <<'EOF' || fail "PNG frames"
import os, sys
sys.path.insert(0, os.environ['TESTS_DIR'])
from png_rgb import read_png_rgb
def read(path):
    w, h, rows = read_png_rgb(path)
    assert (w, h) == (256, 192), '%s: %dx%d' % (path, w, h)
    return rows
for f in range(40):
    read('%s/frame_%06d.png' % (sys.argv[1], f))
pixels = set()
for row in read(sys.argv[1] + '/frame_000020.png'):
    pixels.update(row[i:i + 3] for i in range(0, len(row), 3))
assert len(pixels) > 20, 'frame 20 has %d colours' % len(pixels)
EOF
for f in 000000 000020; do
  for view in aos_depth culling hzm_1 hzm_2; do
    [ -s "$dir/D/frame_${f}_$view.png" ] || fail "no debug view frame_${f}_$view.png"
  done
done
[ -z "$(ls "$dir/D" | grep -v '^frame_0000[02]0_')" ] || fail "debug views of other frames: $(ls "$dir/D")"

# With nothing simplified or culled, the frame is the reference, pixel for pixel.
render --headless --mode full --exact --reference --stats "$dir/full.csv" >/dev/null 2>"$dir/err" ||
  fail "render --mode full: $(cat "$dir/err")"
column "$dir/full.csv" psnr_db | awk '$1 != 100 { bad = 1 } END { exit bad }' || fail "--mode full: PSNR is not 100"
column "$dir/full.csv" changed_pixel_share | awk '$1 != 0 { bad = 1 } END { exit bad }' || fail "--mode full: pixels changed"
column "$dir/full.csv" false_culls | awk '$1 != 0 { bad = 1 } END { exit bad }' || fail "--mode full: false culls"
for c in mse perceptible_share bound_pixels bound_beyond_tau; do
  column "$dir/full.csv" $c | awk '$1 != 0 { bad = 1 } END { exit bad }' || fail "--mode full: $c is not 0"
done
column "$dir/full.csv" ssim | awk '$1 != 1 { bad = 1 } END { exit bad }' || fail "--mode full: SSIM is not 1"
# The budgeted walk's pictures: the summary pools them; a pixel a simplified LOD moved is
# measured to its item, so changed pixels have distances and the bound's columns agree.
grep -q "^reference: PSNR [0-9.]* dB pooled .* perceptibly (CIEDE2000 > 2); SSIM 0\.[0-9]* (mean); bound: " "$dir/out" ||
  fail "summary: $(grep reference "$dir/out")"
paste -d, <(column "$dir/s.csv" changed_pixel_share) <(column "$dir/s.csv" bound_pixels) <(column "$dir/s.csv" bound_beyond_tau) |
  awk -F, '($1 > 0) != ($2 > 0) || $3 > $2 { bad = 1 } END { exit bad }' || fail "bound_pixels does not follow the changed pixels"
column "$dir/s.csv" ssim | awk '!($1 > 0.5 && $1 <= 1) { bad = 1 } END { exit bad }' || fail "SSIM out of (0.5, 1]"

# --colours uniform: every item the same grey, so a frame's pixels are greys or the background
# (0.08, 0.09, 0.11), and many shades of grey (the shading is unchanged); 100 dB against its own
# reference.
render --headless --mode full --reference --colours uniform --out "$dir/U" --stats "$dir/u.csv" \
  >/dev/null 2>"$dir/err" || fail "render --colours uniform: $(cat "$dir/err")"
column "$dir/u.csv" psnr_db | awk '$1 != 100 { bad = 1 } END { exit bad }' || fail "--colours uniform: PSNR is not 100"
python3 - "$dir/U/frame_000020.png" <<'EOF' || fail "--colours uniform: $dir/U/frame_000020.png"
import os, sys
sys.path.insert(0, os.environ['TESTS_DIR'])
from png_rgb import read_png_rgb
w, h, rows = read_png_rgb(sys.argv[1])
background = (20, 23, 28)
greys, other = set(), 0
for row in rows:
    for i in range(0, len(row), 3):
        p = row[i:i + 3]
        if all(abs(p[c] - background[c]) <= 1 for c in range(3)): continue
        if p[0] == p[1] == p[2]: greys.add(p[0])
        else: other += 1
assert other == 0, '%d pixels neither grey nor background' % other
assert len(greys) > 10, 'only %d greys' % len(greys)
EOF

# --colours model, the default: every lit pixel is a shade of one of the model's materials
# (gen plant writes its colours as glTF baseColorFactor, linear): decoded from sRGB, a pixel is
# its material's colour times the light (0.2 to 1). The id pastels of --colours object are not.
render --headless --out "$dir/M" >/dev/null 2>"$dir/err" || fail "render (model colours): $(cat "$dir/err")"
render --headless --colours object --out "$dir/O" >/dev/null 2>"$dir/err" || fail "render --colours object: $(cat "$dir/err")"
# With the hierarchy, from outside (an orbit: HLODs), the HLODs' vertices carry their objects'
# colours (issue 49): the same holds, and few pixels change perceptibly against full detail.
"$exe" path orbit "$dir/p.oss" --frames 40 -o "$dir/orbit.cam" 2>/dev/null || fail "path orbit"
"$exe" render "$dir/p.oss" --path "$dir/orbit.cam" --size 256x192 --headless --hierarchy on --reference --out "$dir/H" \
  --stats "$dir/h.csv" >"$dir/hout" 2>"$dir/err" || fail "render --hierarchy on: $(cat "$dir/err")"
column "$dir/h.csv" objects_drawn | awk '$1 > 0 && $1 < 400 { n++ } END { exit !(n >= 30) }' ||
  fail "the orbit with the hierarchy does not draw HLODs: $(column "$dir/h.csv" objects_drawn | tr '\n' ' ')"
column "$dir/h.csv" perceptible_share | awk '{ s += $1 } END { exit !(s / NR < 2) }' ||
  fail "with the hierarchy, perceptibly changed pixels: $(column "$dir/h.csv" perceptible_share | tr '\n' ' ')"
python3 - "$dir/p.glb" "$dir/M/frame_000020.png" "$dir/O/frame_000020.png" "$dir/H/frame_000020.png" <<'EOF' || fail "--colours model: $dir/M/frame_000020.png"
import json, os, struct, sys
sys.path.insert(0, os.environ['TESTS_DIR'])
from png_rgb import read_png_rgb
glb = open(sys.argv[1], 'rb').read()
length, kind = struct.unpack('<I4s', glb[12:20])
materials = [m['pbrMetallicRoughness']['baseColorFactor'][:3] for m in json.loads(glb[20:20 + length])['materials']]
def linear(c):
    c /= 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
def share_of_material_shades(path):
    w, h, rows = read_png_rgb(path)
    lit = matched = 0
    for row in rows:
        for i in range(0, len(row), 3):
            p = [linear(v) for v in row[i:i + 3]]
            if max(p) < 0.03: continue  # the background and the darkest shading
            lit += 1
            for m in materials:
                s = sum(a * b for a, b in zip(p, m)) / sum(b * b for b in m)
                if 0.15 <= s <= 1.05 and max(abs(a - s * b) for a, b in zip(p, m)) <= 0.02 + 0.03 * max(p):
                    matched += 1
                    break
    return matched / max(1, lit)
model, ids, hlods = [share_of_material_shades(p) for p in sys.argv[2:5]]
print('model %.3f object %.3f hierarchy %.3f' % (model, ids, hlods))
assert model >= 0.95, 'model colours: %.3f of the lit pixels are shades of a material' % model
assert ids < 0.5, '--colours object: %.3f of the lit pixels are shades of a material' % ids
assert hlods >= 0.95, 'model colours with the hierarchy: %.3f of the lit pixels are shades of a material' % hlods
EOF

# Impossible options: exit 2, one error line, no stats file.
: >"$dir/file"
while read -r what options; do
  # shellcheck disable=SC2086
  "$exe" render "$dir/p.oss" $options --stats "$dir/bad.csv" </dev/null >/dev/null 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "$what: exit $status: $(cat "$dir/err")"
  [ "$(wc -l <"$dir/err")" -eq 1 ] && grep -q "^error: " "$dir/err" || fail "$what: $(cat "$dir/err")"
  [ ! -e "$dir/bad.csv" ] || fail "$what: wrote a stats file"
  [ ! -e "$dir/D2" ] || fail "$what: created the --debug-views folder"
done <<EOF
exact-without-display --path $dir/walk.cam --no-display --exact
debug-frames-without-views --path $dir/walk.cam --headless --debug-frames 5
debug-frames-past-the-path --path $dir/walk.cam --headless --debug-views $dir/D2 --debug-frames 999
out-is-a-file --path $dir/walk.cam --headless --out $dir/file
headless-without-path --headless
EOF

# A run that fails midway (a frame's PNG cannot be written) or at once (a corrupt scene) leaves
# no stats file, not even a partial one.
mkdir -p "$dir/G/frame_000005.png"
render --headless --out "$dir/G" --stats "$dir/mid.csv" >/dev/null 2>"$dir/err"; status=$?
[ $status -eq 2 ] && grep -q "frame_000005.png" "$dir/err" || fail "unwritable frame 5: exit $status: $(cat "$dir/err")"
[ -e "$dir/G/frame_000004.png" ] || fail "frames before the failure are missing"
[ ! -e "$dir/mid.csv" ] && [ ! -e "$dir/mid.csv.tmp" ] || fail "a failed run left a stats file"
head -c 5000 "$dir/p.oss" >"$dir/cut.oss"
"$exe" render "$dir/cut.oss" --path "$dir/walk.cam" --headless --stats "$dir/cut.csv" >/dev/null 2>"$dir/err"; status=$?
[ $status -eq 2 ] && grep -q "^error: .*cut.oss" "$dir/err" || fail "corrupt scene: exit $status: $(cat "$dir/err")"
[ ! -e "$dir/cut.csv" ] && [ ! -e "$dir/cut.csv.tmp" ] || fail "a corrupt scene left a stats file"
echo ok
