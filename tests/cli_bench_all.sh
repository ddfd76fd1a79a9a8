#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch bench all --size tiny end to end: prepares its scenes, runs every experiment (with
# 3 MPI ranks when mpirun is there), writes the CSVs, summary.md and eight PNG plots whose
# numbers hold the invariants (0 false culls, 1 frame of switch latency, deltas smaller than
# full sets); a second run, --no-mpi --only 5,9, reuses the scenes, prepares a corrupted one
# again, measures the layouts on 1 rank and says which sections it left out; impossible
# options exit 2; a failing run exits 1, names its log and leaves the earlier results intact.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
out=$dir/out
csv_field() {  # csv_field FILE ROW COLUMN: the value in data row ROW (1 = first) of COLUMN
  awk -F, -v row="$2" -v name="$3" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == name) c = i; next }
    NR == row + 1 { if (!c) exit 3; print $c }' "$1"
}

"$exe" bench all --size tiny --out "$out" >"$dir/stdout" 2>"$dir/stderr" || { cat "$dir/stderr"; fail "bench all"; }
[ "$(cat "$dir/stdout")" = "$out/summary.md" ] || fail "stdout is not the summary's path: $(cat "$dir/stdout")"
for k in 1 2 3 4 5 6 7 8 9; do
  grep -q "^bench all \[$k/9\] " "$dir/stderr" || fail "no progress line for experiment $k"
done
# Section 9: bench links on the grid (no link; 0, 1 and 5 ms at 100 Mb/s; the narrow link), one frame
# of latency in every run.
[ "$(tail -n +2 "$out/links/links.csv" | wc -l)" -eq 5 ] || fail "links/links.csv: not 5 runs"
awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "latency_frames") c = i; next } $c != "1.000" { bad = 1 } END { exit bad || !c }' \
  "$out/links/links.csv" || fail "links: latency not one frame: $(cat "$out/links/links.csv")"
grep -q "^## 9. Emulated links" "$out/summary.md" || fail "summary.md has no section 9"
grep -q "^### The latency budget" "$out/summary.md" || fail "section 9 lacks the latency budget"
for f in breakdown accuracy accuracy_frames streaming bytes bytes_frames latency fps_frames scaling hierarchy; do
  [ "$(wc -l <"$out/$f.csv")" -ge 2 ] || fail "$f.csv has no rows"
done
[ "$(head -c 8 "$out/plots/links.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "plots/links.png is not a PNG"
for p in breakdown accuracy streaming bytes latency fps scaling hierarchy; do
  [ -s "$out/plots/$p.gp" ] || fail "no plots/$p.gp"
  [ "$(head -c 8 "$out/plots/$p.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "plots/$p.png is not a PNG"
  [ "$(stat -c %s "$out/plots/$p.png")" -gt 10000 ] || fail "plots/$p.png is nearly empty"
done
for heading in "## 1. Frame time per stage" "## 2. Culling accuracy" "## 3. Streaming" "## 4. Visible-set bytes" \
               "## 5. Camera-to-display latency" "## 6. Frames per second" "## 7. Scaling" "## 8. The hierarchy"; do
  grep -q "^$heading" "$out/summary.md" || fail "summary.md lacks '$heading'"
done

# oc+lod against lod with drawing and without (the pipeline alone), per scene, in section 6 and
# the headline table; the occlusion stage's ms and the raster's rate where oc+lod ran.
[ "$(grep -c "^| engine grid .* | [0-9.]*x | \(yes\|no\) ([0-9.]* against [0-9.]*) | [0-9.]* | [0-9 ]* | [0-9.]* |$" "$out/summary.md")" -ge 1 ] ||
  fail "section 6 lacks the grid's row without drawing"
grep -q "^| plant .* | [0-9.]*x | \(yes\|no\) ([0-9.]* against [0-9.]*) | [0-9.]* | [0-9 ]* | [0-9.]* |$" "$out/summary.md" ||
  fail "section 6 lacks the plant's row without drawing"
grep -q "^| frame rate, oc+lod over lod alone, drawing on llvmpipe | [0-9.]*x (grid), [0-9.]*x (plant) |" "$out/summary.md" ||
  fail "the headline lacks oc+lod over lod with drawing"
grep -q "^| the same without drawing (.*) | [0-9.]*x (grid, occlusion [0-9.]* ms, raster [0-9.]* M tri/s per core), " "$out/summary.md" ||
  fail "the headline lacks oc+lod over lod without drawing"

# The numbers: 3 modes x 2 scenes; conservative culling; deltas smaller; the switch's one frame.
[ "$(tail -n +2 "$out/breakdown.csv" | wc -l)" -eq 6 ] || fail "breakdown.csv: not 6 rows"
# The hierarchy: 2 scenes x (orbit flat / hierarchy, walk flat / hierarchy / visibility-weighted), each
# with a PSNR against full detail.
[ "$(tail -n +2 "$out/hierarchy.csv" | wc -l)" -eq 10 ] || fail "hierarchy.csv: not 10 rows"
for row in 1 2 3 4 5 6 7 8 9 10; do
  awk -v p="$(csv_field "$out/hierarchy.csv" $row psnr_db)" 'BEGIN { exit !(p > 15 && p <= 100) }' ||
    fail "hierarchy.csv row $row: PSNR out of (15, 100]"
done
for row in 1 2; do
  [ "$(csv_field "$out/accuracy.csv" $row false_culls)" = 0 ] || fail "false culls in accuracy.csv row $row"
  awk -v a="$(csv_field "$out/accuracy.csv" $row accuracy_ratio_of_sums)" 'BEGIN { exit !(a > 50 && a <= 100) }' ||
    fail "accuracy row $row out of (50, 100]"
done
awk -v d="$(csv_field "$out/bytes.csv" 1 delta_bytes_per_frame)" -v f="$(csv_field "$out/bytes.csv" 1 full_set_bytes_per_frame_sent)" \
  'BEGIN { exit !(d > 0 && d < f) }' || fail "deltas not smaller than full sets: $(cat "$out/bytes.csv")"
[ "$(csv_field "$out/latency.csv" 1 latency_frames)" = 0 ] || fail "1 rank: latency not 0 frames"
if command -v mpirun >/dev/null; then
  [ "$(tail -n +2 "$out/latency.csv" | wc -l)" -eq 3 ] || fail "latency.csv: not 3 layouts"
  for row in 2 3; do
    [ "$(csv_field "$out/latency.csv" $row latency_frames)" = 1 ] || fail "layout row $row: latency not 1 frame"
  done
fi
[ "$(tail -n +2 "$out/scaling.csv" | wc -l)" -eq 3 ] || fail "scaling.csv: not 3 scenes"
awk -F, 'NR > 2 && $3 <= prev { exit 1 } { prev = $3 }' "$out/scaling.csv" || fail "scaling: triangles do not grow"
[ "$(tail -n +2 "$out/streaming.csv" | wc -l)" -eq 6 ] || fail "streaming.csv: not SC/SnC/NS x 2 scenes"
sc=$(csv_field "$out/streaming.csv" 1 streamed_triangles_per_frame)
snc=$(csv_field "$out/streaming.csv" 2 streamed_triangles_per_frame)
awk -v a="$sc" -v b="$snc" 'BEGIN { exit !(a < b) }' || fail "SC streams no less than SnC ($sc vs $snc)"

# A second run, without MPI and of the experiments MPI changes only (--only 5,9: 4 comes with
# 5), reuses the first run's scenes (one truncated scene is prepared again); the layouts run on
# 1 rank, and the summary says so and which sections were left out.
truncate -s 1000 "$out/scenes/plant_400.oss"
"$exe" bench all --size tiny --no-mpi --only 5,9 --scenes "$out/scenes" --out "$dir/nompi" >/dev/null 2>"$dir/stderr2" ||
  { cat "$dir/stderr2"; fail "second run (--no-mpi)"; }
grep -q "scene engine grid 2x1x2: .*(reused" "$dir/stderr2" || fail "second run did not reuse the grid"
grep -q "plant_400.oss does not verify; preparing it again" "$dir/stderr2" || fail "corrupt scene not prepared again"
"$exe" verify "$out/scenes/plant_400.oss" >/dev/null || fail "the scene prepared again does not verify"
for k in 4 5 9; do
  grep -q "^bench all \[$k/9\] " "$dir/stderr2" || fail "--only 5,9: no progress line for experiment $k"
done
for k in 1 2 3 6 7 8; do
  grep -q "^bench all \[$k/9\] " "$dir/stderr2" && fail "--only 5,9: experiment $k ran"
  grep -A2 "^## $k\. " "$dir/nompi/summary.md" | grep -q "^Not run: \`--only 5,9\` left it out" ||
    fail "--only 5,9: section $k does not say it was not run"
done
ls "$dir/nompi/plots" | grep -qE '^(breakdown|hierarchy)\.png$' && fail "--only 5,9: plots of experiments not run"
[ -s "$dir/nompi/plots/latency.png" ] || fail "--only 5,9: no plots/latency.png"
grep -q "^Not run: --no-mpi" "$dir/nompi/summary.md" || fail "--no-mpi: section 9 does not say it was not run"
[ "$(tail -n +2 "$dir/nompi/latency.csv" | wc -l)" -eq 1 ] || fail "--no-mpi: not 1 layout"
grep -q "^- note: --no-mpi: the layouts were measured with 1 rank only" "$dir/nompi/summary.md" || fail "--no-mpi: no note"

# Impossible options: exit 2, one error line, nothing run.
for bad in "--size huge --out $dir/x" "--size tiny" "--size tiny --out $dir/x --only 10" \
           "--size tiny --out $dir/x --only 2,x" "--size tiny --out $dir/x --model $dir/none.glb"; do
  "$exe" bench all $bad >/dev/null 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "bench all $bad: exit $status, expected 2"
  [ "$(wc -l <"$dir/err")" -eq 1 ] && grep -q "^error: " "$dir/err" || fail "bench all $bad: $(cat "$dir/err")"
done
grep -q "none.glb" "$dir/err" || fail "missing model not named: $(cat "$dir/err")"

# A run that fails (a malformed model to tile) exits 1, names the failed step's log, and leaves
# the earlier summary and CSVs as they were.
cp "$out/summary.md" "$dir/summary.before"
cp "$out/breakdown.csv" "$dir/breakdown.before"
bad_model=$(dirname "$0")/bad/glb_truncated_bin.glb
"$exe" bench all --size tiny --out "$out" --scenes "$dir/fresh" --model "$bad_model" >/dev/null 2>"$dir/err"; status=$?
[ $status -eq 1 ] || fail "failing run: exit $status, expected 1"
grep -q "^error: bench all: gen_grid_2x1x2 failed (exit status 2); its log: $out/logs/gen_grid_2x1x2.log" "$dir/err" ||
  fail "failing run: $(cat "$dir/err")"
grep -q "glb_truncated_bin.glb" "$out/logs/gen_grid_2x1x2.log" || fail "the log does not name the bad model"
cmp -s "$out/summary.md" "$dir/summary.before" || fail "a failed run changed summary.md"
cmp -s "$out/breakdown.csv" "$dir/breakdown.before" || fail "a failed run changed breakdown.csv"
ls "$out" | grep -q '\.tmp$' && fail "temporary files left in $out"
echo "ok"
