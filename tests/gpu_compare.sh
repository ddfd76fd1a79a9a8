#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Whole frames on the CPU and on the GPU (issue 12): the same headless walk with occswitch (CPU
# kernels) and occswitch-cuda, compared frame by frame. The PVS (pvs_hash, objects_visible) must
# be identical: the depth raster snaps to integers and the kernels are built without fused
# multiply-adds, so the occlusion test is the same computation on both. The LOD counts may
# differ by rounding, since CUDA's logf and expf are not glibc's (within 2 ulp), and with them
# the drawn triangles and the pictures: the tolerance is 1 % of the drawn triangles per frame;
# frames whose LOD counts (visible_hash) or pictures differ at all are counted and printed.
# Without an OpenGL context the runs go on without drawing (--no-display) and say so.
#   gpu_compare.sh OCCSWITCH OCCSWITCH_CUDA SCENE.oss PATH.cam OUT_DIR
#   gpu_compare.sh OCCSWITCH OCCSWITCH_CUDA --generated OUT_DIR   (a 4x1x4 engine grid and a
#                                                                   2000-object plant, walked)
# Exit 0: identical; 1: a difference or a failed run; 77: no usable GPU (CTest's skip).
set -u
if [ "${3:-}" = "--generated" ]; then
  cpu=$1 gpu=$2 out=$4
  mkdir -p "$out"
  engine=/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb
  "$cpu" gen grid --model "$engine" --nx 4 --ny 1 --nz 4 -o "$out/grid.glb" >/dev/null &&
    "$cpu" prep "$out/grid.glb" -o "$out/grid.oss" >/dev/null &&
    "$cpu" path walk "$out/grid.oss" --frames 40 -o "$out/grid.cam" >/dev/null &&
    "$cpu" gen plant --objects 2000 -o "$out/plant.glb" >/dev/null &&
    "$cpu" prep "$out/plant.glb" -o "$out/plant.oss" >/dev/null &&
    "$cpu" path walk "$out/plant.oss" --frames 40 -o "$out/plant.cam" >/dev/null ||
    { echo "FAIL: preparing the scenes"; exit 1; }
  status=0
  for scene in grid plant; do
    bash "$0" "$cpu" "$gpu" "$out/$scene.oss" "$out/$scene.cam" "$out"; s=$?
    [ $s -eq 77 ] && exit 77
    [ $s -ne 0 ] && status=1
  done
  exit $status
fi
cpu=$1 gpu=$2 scene=$3 path=$4 out=$5
mkdir -p "$out"
name=$(basename "$scene" .oss)
common=(render "$scene" --path "$path" --size 256x256)
# With pictures where an OpenGL context can be had; where none can (a compute-only driver, no
# EGL vendor library), the same runs without drawing, which still compare the PVS, the triangle
# counts, the bus bytes and the stage times.
drawing=(--headless --out "$out/$name-cuda")
run_gpu() { "$gpu" "${common[@]}" "${drawing[@]}" --stats "$out/$name-cuda.csv" >"$out/$name-cuda.txt" 2>&1; }
if ! run_gpu; then
  if grep -q "no usable CUDA device" "$out/$name-cuda.txt"; then
    echo "SKIP: $(grep -m1 error "$out/$name-cuda.txt")"
    exit 77
  fi
  if grep -q "no headless OpenGL" "$out/$name-cuda.txt"; then
    echo "NOTE: $name: $(grep -m1 "no headless OpenGL" "$out/$name-cuda.txt")"
    echo "NOTE: $name: compared without drawing (--no-display): PVS, triangle counts, bus bytes, stage times; no pictures"
    drawing=(--no-display)
    run_gpu || { echo "FAIL: occswitch-cuda on $name:"; cat "$out/$name-cuda.txt"; exit 1; }
  else
    echo "FAIL: occswitch-cuda on $name:"; cat "$out/$name-cuda.txt"; exit 1
  fi
fi
[ "${drawing[0]}" = --headless ] && drawing=(--headless --out "$out/$name-cpu")
"$cpu" "${common[@]}" "${drawing[@]}" --stats "$out/$name-cpu.csv" >"$out/$name-cpu.txt" 2>&1 ||
  { echo "FAIL: occswitch on $name:"; cat "$out/$name-cpu.txt"; exit 1; }
grep -E '^(device|display):' "$out/$name-cuda.txt" | sed 's/^/cuda: /'
grep -E '^(device|display):' "$out/$name-cpu.txt" | sed 's/^/cpu:  /'

# Columns by name, so that the comparison survives new columns.
awk -F, '
  FNR == 1 { for (i = 1; i <= NF; ++i) at[FILENAME, $i] = i; next }
  FILENAME == ARGV[1] { row[FNR] = $0; next }
  {
    split(row[FNR], a, ",")
    for (k = 1; k <= 2; ++k) {
      c = k == 1 ? "objects_visible" : "pvs_hash"
      x = a[at[ARGV[1], c]]; y = $(at[FILENAME, c])
      if (x != y) { printf "frame %d: %s cpu %s cuda %s (the PVS must be identical)\n", FNR - 2, c, x, y; bad++ }
    }
    if (a[at[ARGV[1], "visible_hash"]] != $(at[FILENAME, "visible_hash"])) lod++
    x = a[at[ARGV[1], "active_triangles"]]; y = $(at[FILENAME, "active_triangles"])
    d = x > y ? x - y : y - x
    if (d > 0.01 * x) { printf "frame %d: drawn triangles cpu %s cuda %s (over 1 %%)\n", FNR - 2, x, y; bad++ }
  }
  END { printf "%d frames with LOD counts that differ by rounding\n", lod; exit bad > 0 }' \
  "$out/$name-cpu.csv" "$out/$name-cuda.csv" | tail -21
columns_ok=${PIPESTATUS[0]}

pictures=0 differ=0
for f in "$out/$name-cpu"/*.png; do
  [ -e "$f" ] || break  # compared without drawing
  pictures=$((pictures + 1))
  cmp -s "$f" "$out/$name-cuda/$(basename "$f")" || differ=$((differ + 1))
done

# Means over frames after the first: the bus and the stage times.
for build in cpu cuda; do
  awk -F, -v build=$build '
    FNR == 1 { for (i = 1; i <= NF; ++i) at[$i] = i; next }
    FNR > 2 { n++; h += $(at["bus_h2d_bytes"]); d += $(at["bus_d2h_bytes"]); s += $(at["streamed_bytes"])
              v += $(at["objects_visible"]); t += $(at["ms_total"]); dr += $(at["ms_draw"])
              for (k in at) if (k ~ /^ms_/) ms[k] += $(at[k]) }
    END { if (!n) exit
          printf "%-4s bus %.0f B/frame to the device + %.0f back, streamed %.0f, %.1f visible; frame %.2f ms, draw %.2f ms:",
                 build, h / n, d / n, s / n, v / n, t / n, dr / n
          for (k in ms) if (k != "ms_total" && k != "ms_draw" && k != "ms_exact" && k != "ms_wait") printf " %s %.2f", substr(k, 4), ms[k] / n
          printf "\n" }' "$out/$name-$build.csv"
done
echo "$name: $pictures frames, $differ pictures differ between the CPU and CUDA builds"
[ "$columns_ok" -eq 0 ] || { echo "FAIL: $name differs beyond the tolerance (see above)"; exit 1; }
echo "PASS: $name: the same PVS on CPU and GPU, drawn triangles within 1 %"
