#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch bench prep end to end on the default model (the engine), shortened: one timed run, a
# second of the OpenMesh reference, few error samples. It writes prep_bench.csv with every mesh at
# the three targets (50, 10, 1 %) and prep_summary.md with the throughput and the comparison with
# meshoptimizer; impossible options and a missing model exit 2 and write nothing.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
out=$dir/out

"$exe" bench prep --repeat 1 --openmesh-seconds 1 --samples 500 --out "$out" >"$dir/stdout" 2>"$dir/stderr" ||
  { cat "$dir/stderr"; fail "bench prep"; }
[ -s "$out/prep_bench.csv" ] && [ -s "$out/prep_summary.md" ] || fail "no prep_bench.csv or prep_summary.md"
grep -q "^wrote $out/prep_bench.csv and $out/prep_summary.md" "$dir/stderr" || fail "the files are not named"
grep -q "^throughput: ours .* M tri/s" "$out/prep_summary.md" || fail "no throughput in the summary"
grep -q "OpenMesh reference" "$out/prep_summary.md" || fail "no OpenMesh reference in the summary"
# Every mesh at each of the three targets once, with non-negative errors (infinite only for a LOD
# that vanished: 0 triangles) and no more triangles than its welded input.
awk -F, 'function error_ok(e, tris) { return e == "inf" ? tris + 0 == 0 : e ~ /^[0-9.e+-]+$/ && e + 0 >= 0 }
  NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
  { n[$(c["mesh"])] += 1; t[$(c["mesh"]) "," $(c["target_percent"])] += 1; rows += 1
    if (!error_ok($(c["ours_error"]), $(c["ours_triangles"]))) { print "ours_error " $(c["ours_error"]); bad = 1 }
    if (!error_ok($(c["meshopt_error"]), $(c["meshopt_triangles"]))) { print "meshopt_error " $(c["meshopt_error"]); bad = 1 }
    if ($(c["ours_triangles"]) + 0 > $(c["welded_triangles"]) + 0) { print "ours above its input"; bad = 1 } }
  END { if (rows == 0) { print "no rows"; exit 1 }
        for (m in n) if (n[m] != 3 || t[m ",50"] != 1 || t[m ",10"] != 1 || t[m ",1"] != 1) { print "mesh " m; exit 1 }
        exit bad }' "$out/prep_bench.csv" || fail "prep_bench.csv rows"

expect_usage() {  # expect_usage WORDS ARGS...: exit 2, one error line with WORDS, no files
  local words=$1
  shift
  "$exe" bench prep "$@" --out "$dir/bad" >/dev/null 2>"$dir/err"
  [ $? -eq 2 ] || fail "bench prep $*: exit status not 2"
  grep -q "$words" "$dir/err" || fail "bench prep $*: no '$words' in: $(cat "$dir/err")"
  [ ! -e "$dir/bad/prep_bench.csv" ] || fail "bench prep $*: wrote a result"
}
expect_usage "openmesh-seconds" --openmesh-seconds -1
expect_usage "thread count" --threads 5000
expect_usage "$dir/none.glb" "$dir/none.glb"
echo "bench prep: $(grep -c . "$out/prep_bench.csv") CSV lines"
