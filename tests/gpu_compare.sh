#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Whole frames on the CPU and on the GPU (issue 12): the same headless walk with occswitch (CPU
# kernels) and occswitch-cuda, compared frame by frame: the visible set with its LOD counts
# (visible_hash), the drawn and streamed triangles, and the picture's bytes (which the reformed
# triangles decide). Prints what the bus carried and the stage times of both.
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
common=(render "$scene" --path "$path" --headless --size 256x256)
if ! "$gpu" "${common[@]}" --out "$out/$name-cuda" --stats "$out/$name-cuda.csv" >"$out/$name-cuda.txt" 2>&1; then
  if grep -q "no usable CUDA device" "$out/$name-cuda.txt"; then
    echo "SKIP: $(grep -m1 error "$out/$name-cuda.txt")"
    exit 77
  fi
  echo "FAIL: occswitch-cuda on $name:"; cat "$out/$name-cuda.txt"; exit 1
fi
"$cpu" "${common[@]}" --out "$out/$name-cpu" --stats "$out/$name-cpu.csv" >"$out/$name-cpu.txt" 2>&1 ||
  { echo "FAIL: occswitch on $name:"; cat "$out/$name-cpu.txt"; exit 1; }
grep -E '^(device|display):' "$out/$name-cuda.txt" | sed 's/^/cuda: /'
grep -E '^(device|display):' "$out/$name-cpu.txt" | sed 's/^/cpu:  /'

# Columns by name, so that the comparison survives new columns.
compare=objects_visible,visible_hash,objects_drawn,active_triangles,resident_triangles,streamed_triangles
awk -F, -v cols="$compare" '
  FNR == 1 { for (i = 1; i <= NF; ++i) at[FILENAME, $i] = i; next }
  FILENAME == ARGV[1] { row[FNR] = $0; next }
  {
    split(row[FNR], a, ","); n = split(cols, c, ",")
    for (k = 1; k <= n; ++k) {
      x = a[at[ARGV[1], c[k]]]; y = $(at[FILENAME, c[k]])
      if (x != y) { printf "frame %d: %s cpu %s cuda %s\n", FNR - 2, c[k], x, y; bad++ }
    }
  }
  END { exit bad > 0 }' "$out/$name-cpu.csv" "$out/$name-cuda.csv" | head -20
columns_ok=${PIPESTATUS[0]}

pictures=0 differ=0
for f in "$out/$name-cpu"/*.png; do
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
[ "$columns_ok" -eq 0 ] && [ "$differ" -eq 0 ] || { echo "FAIL: $name differs (see above)"; exit 1; }
echo "PASS: $name identical on CPU and GPU"
