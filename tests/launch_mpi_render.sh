#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# launch/mpi-render: runs 3 ranks through a hostfile with rank 0 on the display host, and
# refuses what cannot work with one error line and exit 2.
set -u
exe=$1
root=$(cd "$(dirname "$0")/.." && pwd)
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
export OCCSWITCH=$exe
"$exe" gen plant --objects 200 -o "$dir/p.glb" 2>/dev/null || fail "gen"
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" 2>/dev/null || fail "prep"
"$exe" path walk "$dir/p.oss" --frames 20 -o "$dir/w.cam" 2>/dev/null || fail "path"
echo "localhost slots=3" >"$dir/hosts"
mkdir "$dir/tmp"
out=$(TMPDIR="$dir/tmp" timeout 120 "$root/launch/mpi-render" --hostfile "$dir/hosts" -- "$dir/p.oss" --path "$dir/w.cam" --no-display \
      --stats "$dir/s.csv" 2>"$dir/err") || fail "mpi-render: $(tail -5 "$dir/err")"
echo "$out" | grep -q "20 frames at .* 3 ranks" || fail "summary: $out"
[ -z "$(find "$dir/tmp" -name 'occswitch-rankfile.*')" ] || fail "the rankfile was left behind: $(ls "$dir/tmp")"
[ "$(cut -d, -f1 "$dir/s.csv" | sort -u | tr '\n' ' ')" = "0 1 2 rank " ] || fail "ranks in the CSV: $(cut -d, -f1 "$dir/s.csv" | sort -u)"
dry=$("$root/launch/mpi-render" --dry-run --hostfile "$root/launch/hostfile.example" --display-host render-node-2 -- x.oss)
echo "$dry" | grep -q "rank 0=render-node-2" || fail "display host: $dry"
echo "$dry" | grep -q "odls_base_sigkill_timeout 3" || fail "fault flags: $dry"
for bad in "-n 65 -- x.oss" "-n two -- x.oss" "--hostfile $dir/missing -- x.oss" "--display-host h -- x.oss" "--bogus" ""; do
  # shellcheck disable=SC2086
  "$root/launch/mpi-render" $bad >/dev/null 2>"$dir/err"; status=$?
  [ $status -eq 2 ] || fail "mpi-render $bad: exit $status"
  grep -q "^error: mpi-render: " "$dir/err" || fail "mpi-render $bad: $(cat "$dir/err")"
done
echo ok
