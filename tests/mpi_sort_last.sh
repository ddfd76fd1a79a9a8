#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Sort-last display ranks: `mpirun -np 4` and `-np 5` (the occlusion switch and 2 or 3 display
# ranks, each drawing its partition, depth-composited with MPI's collectives into rank 0's
# picture) write the same PNG frames as `-np 3`, pixel for pixel, or (where two partitions' depths
# tie) at a PSNR of at least 60 dB; after an orbit, which sees the whole plant, each display rank
# holds a share of the resident geometry near 1/P (between 0.5/P and 1.5/P). A display rank
# killed mid-run (in the middle of the compositing collectives), or stopped (SIGSTOP: silent),
# ends the whole job within 10 s, the others naming it.
set -u
export TESTS_DIR; TESTS_DIR=$(cd "$(dirname "$0")" && pwd)
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"; [ -n "${job:-}" ] && kill -9 $job 2>/dev/null' EXIT
fail() { echo "FAIL: $*"; exit 1; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpirun=(mpirun --oversubscribe --mca odls_base_sigkill_timeout 3)
"$exe" gen plant --objects 800 -o "$dir/p.glb" 2>/dev/null || fail "gen"
# A flat scene: render refines a .oss's hierarchy on 1 to 3 ranks but not on 2 + P, whose
# partitions are of objects; these layouts are compared frame by frame (the hierarchy through
# the switch: tests/mpi_hierarchy.sh).
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" --hierarchy off 2>/dev/null || fail "prep"
"$exe" path walk "$dir/p.oss" --frames 24 -o "$dir/walk.cam" 2>/dev/null || fail "path walk"
"$exe" path orbit "$dir/p.oss" --frames 12 -o "$dir/orbit.cam" 2>/dev/null || fail "path orbit"
{ cat "$dir/walk.cam"; grep -v '^#' "$dir/orbit.cam"; } >"$dir/path.cam"
for n in 3 4 5; do
  timeout 180 "${mpirun[@]}" -np $n "$exe" render "$dir/p.oss" --path "$dir/path.cam" --headless --size 200x150 \
    --out "$dir/f$n" --stats "$dir/s$n.csv" >"$dir/out$n" 2>"$dir/err$n" || fail "mpirun -np $n: $(tail -5 "$dir/err$n")"
done
grep -q "^sort-last: 2 display ranks" "$dir/out4" || fail "-np 4: $(cat "$dir/out4")"
grep -q "^sort-last: 3 display ranks" "$dir/out5" || fail "-np 5: $(cat "$dir/out5")"
grep -q "^sort-last" "$dir/out3" && fail "-np 3 printed a sort-last line"
python3 - "$dir" <<'PY' || fail "pictures of 2 + P ranks against 3 ranks"
import csv, math, os, sys
sys.path.insert(0, os.environ["TESTS_DIR"])
from png_rgb import read_png_rgb
d = sys.argv[1]
frames = sorted(os.listdir(f'{d}/f3'))
assert len(frames) == 36, f'{len(frames)} frames from 3 ranks'
for n in (4, 5):
    assert sorted(os.listdir(f'{d}/f{n}')) == frames, f'-np {n}: other frame files'
    identical, lowest = 0, 1e9
    for name in frames:
        a, b = open(f'{d}/f3/{name}', 'rb').read(), open(f'{d}/f{n}/{name}', 'rb').read()
        if a == b:
            identical += 1
            continue
        wa, ha, ra = read_png_rgb(f'{d}/f3/{name}')
        wb, hb, rb = read_png_rgb(f'{d}/f{n}/{name}')
        assert (wa, ha) == (wb, hb) == (200, 150), name
        se = sum((x - y) ** 2 for p, q in zip(ra, rb) for x, y in zip(p, q))
        psnr = 100.0 if se == 0 else 10 * math.log10(255 ** 2 * 3 * wa * ha / se)
        lowest = min(lowest, psnr)
        assert psnr >= 60, f'-np {n} {name}: PSNR {psnr:.2f} dB against -np 3'
    print(f'-np {n}: {identical} of {len(frames)} frames identical' + ('' if lowest > 1e8 else f', lowest PSNR {lowest:.2f} dB'))
    rows = [r for r in csv.DictReader(open(f'{d}/s{n}.csv')) if r['role'] == 'rvg']
    held = [int(r['resident_triangles']) for r in rows if int(r['frame']) == 35]
    parts = n - 2
    assert len(held) == parts and all(0.5 / parts <= h / sum(held) <= 1.5 / parts for h in held), \
        f'-np {n}: resident triangles per display rank after the orbit {held}'
    print(f'-np {n}: resident triangles per display rank after the orbit {held}')
    assert all(int(r['bytes_composite']) > 0 for r in rows), f'-np {n}: a display row without composite bytes'
PY
# A display rank killed (rank 4) or silent (rank 3, SIGSTOP, --rank-timeout 3) mid-run.
"$exe" path walk "$dir/p.oss" --frames 20000 -o "$dir/long.cam" 2>/dev/null || fail "long path"
for fault in kill stop; do
  victim_rank=$([ $fault = kill ] && echo 4 || echo 3)
  "${mpirun[@]}" -np 5 "$exe" render "$dir/p.oss" --path "$dir/long.cam" --headless --size 128x96 --rank-timeout 3 \
    >/dev/null 2>"$dir/errk" &
  job=$!
  victim=
  for _ in $(seq 100); do
    sleep 0.1
    for pid in $(pgrep -f "occswitch render $dir/p.oss --path $dir/long.cam"); do
      tr '\0' '\n' <"/proc/$pid/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$victim_rank" && victim=$pid
    done
    [ -n "$victim" ] && break
  done
  [ -n "$victim" ] || { kill -9 $job; fail "rank $victim_rank never started"; }
  # Mid-run, past the start-up: until the display has finished two frames the ranks allow each
  # other 60 s (a large scene loads for that long). Under ASan, 5 ranks on 2 cores can take
  # longer than 3 s to get there: one run of the suite failed with the stop inside the start-up.
  sleep 8
  kill -0 $job 2>/dev/null || fail "the 5-rank run ended before the $fault: $(tail -3 "$dir/errk")"
  [ $fault = kill ] && kill -9 "$victim" || kill -STOP "$victim"
  killed=$(date +%s.%N)
  for _ in $(seq 150); do kill -0 $job 2>/dev/null || break; sleep 0.1; done
  if kill -0 $job 2>/dev/null; then kill -9 $job "$victim"; fail "ranks still running 15 s after the $fault of rank $victim_rank"; fi
  wait $job; status=$?
  kill -9 "$victim" 2>/dev/null
  took=$(awk -v a="$killed" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')
  [ $status -ne 0 ] || fail "mpirun exit 0 after the $fault of display rank $victim_rank"
  awk -v t="$took" 'BEGIN { exit !(t < 10) }' || fail "$fault of display rank $victim_rank: the job took $took s to end"
  n=$(grep -c "^error: rank $victim_rank: " "$dir/errk")
  [ "$n" -ge 1 ] || fail "$fault: no rank named rank $victim_rank: $(grep error "$dir/errk")"
  echo "$fault of display rank $victim_rank: the job ended in $took s, $n ranks named it"
done
job=
echo ok
