#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# launch/gpu-check --bundle makes a folder a GPU machine without packages can run: every binary
# and library is there, DIR/run makes the scenes with the bundled CPU build, which renders
# through the bundled loader, and passes where there is a GPU or says there is none (exit 3)
# where there is not.
set -u
src=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$src/launch/gpu-check" --no-setup --bundle "$dir/b" >"$dir/bundle.log" 2>&1 || { cat "$dir/bundle.log"; fail "bundle"; }
for f in run bin/occswitch bin/occswitch-cuda bin/occ_tests_cuda \
         bin/gpu_compare.sh lib/ld-linux.so lib/libEGL.so.1 lib/libcudart.so.13 scenes/engine.glb; do
  [ -e "$dir/b/$f" ] || fail "the bundle lacks $f"
done
[ "$(du -sm "$dir/b" | cut -f1)" -lt 64 ] || fail "the bundle is $(du -sm "$dir/b" | cut -f1) MiB"
# compute-sanitizer's reports name source lines: the kernels are built with -lineinfo.
grep -q -- "-lineinfo" "$src/build/CMakeFiles/occ_kernels_cuda.dir/flags.make" || fail "the CUDA kernels lack -lineinfo"
"$dir/b/run" "$dir/results" >"$dir/run.log" 2>&1; status=$?
# The plain CUDA test run comes first and apart from memcheck, which runs last with its own limit.
grep -q '^echo "== occ_tests_cuda"$' "$dir/b/run" || fail "no plain run of occ_tests_cuda"
grep -q "under compute-sanitizer" "$dir/b/run" || fail "memcheck is not in the run script"
[ "$(grep -n -m1 "under compute-sanitizer" "$dir/b/run" | cut -d: -f1)" -gt "$(grep -n -m1 "== CPU and GPU builds, frame by frame" "$dir/b/run" | cut -d: -f1)" ] ||
  fail "memcheck does not come after the comparisons"
cat "$dir/run.log"
if [ $status -eq 3 ]; then
  grep -q "no usable GPU" "$dir/run.log" || fail "exit 3 without saying why"
else
  [ $status -eq 0 ] || fail "DIR/run exited $status"
fi
grep -q "^== occswitch-cuda info --device" "$dir/run.log" || fail "the run does not ask for the device first"
if [ $status -eq 3 ]; then
  # No GPU: the run stopped before making scenes; make them as it would have.
  mkdir -p "$dir/results/scenes"
  {
    "$dir/results/occswitch" gen grid --model "$dir/b/scenes/engine.glb" --nx 4 --ny 1 --nz 4 -o "$dir/results/scenes/grid.glb" &&
    "$dir/results/occswitch" prep "$dir/results/scenes/grid.glb" -o "$dir/results/scenes/grid.oss" &&
    "$dir/results/occswitch" path walk "$dir/results/scenes/grid.oss" --frames 20 -o "$dir/results/scenes/grid.cam"
  } >"$dir/scenes.log" 2>&1 || { cat "$dir/scenes.log"; fail "the bundled CPU build could not make a scene"; }
else
  # DIR/run made the scenes with the bundled CPU build.
  for f in grid.oss grid.cam plant.oss plant.cam; do
    [ -s "$dir/results/scenes/$f" ] || fail "DIR/run did not make scenes/$f"
  done
fi
# The bundled CPU build, through the bundled loader and libraries, renders a frame.
"$dir/results/occswitch" render "$dir/results/scenes/grid.oss" --path "$dir/results/scenes/grid.cam" --no-display \
  >"$dir/cpu.log" 2>&1 || { cat "$dir/cpu.log"; fail "the bundled occswitch"; }
grep -q "^device: " "$dir/cpu.log" || fail "no device line: $(cat "$dir/cpu.log")"
# A benchmark from the bundle starts its child runs through the bundle's wrapper (through
# /proc/self/exe, the bundled loader, every child run would fail).
"$dir/results/occswitch" bench massive --out "$dir/massive" --objects 1000 --frames 12 --exact-frames 2 \
  --reference-frames 0 --growth-objects 100000 --grid 0 >"$dir/massive.log" 2>&1 ||
  { cat "$dir/massive.log"; fail "bench massive from the bundle"; }
[ "$(wc -l <"$dir/massive/massive.csv")" -eq 9 ] || fail "bench massive from the bundle: $(cat "$dir/massive/massive.csv")"
echo "PASS"
