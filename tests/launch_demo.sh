#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# launch/demo on a short walk with the existing build: every file it promises (frames, the
# animated preview, merged stats, the plot of the walk) and the headline numbers it prints,
# with 0 false culls; 3 ranks when mpirun is there.
set -u
root=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$root/launch/demo" --no-setup --frames 12 "$dir/out" >"$dir/stdout" 2>"$dir/stderr" ||
  { tail -20 "$dir/stderr"; fail "demo"; }
[ "$(ls "$dir/out/frames" | grep -c '^frame_[0-9]*\.png$')" -eq 12 ] || fail "not 12 frames"
for f in preview.png walk.png; do
  [ "$(head -c 8 "$dir/out/$f" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "$f is not a PNG"
done
grep -q acTL "$dir/out/preview.png" || fail "preview.png is not animated (no acTL chunk)"
[ "$(stat -c %s "$dir/out/walk.png")" -gt 20000 ] || fail "walk.png is nearly empty"
grep -q "^  exact: 0 false culls" "$dir/stdout" || fail "no '0 false culls' headline: $(cat "$dir/stdout")"
grep -q "^plot of the walk: $dir/out/walk.png" "$dir/stdout" || fail "plot path not printed"
if command -v mpirun >/dev/null; then
  grep -q "3 ranks" "$dir/stdout" || fail "not run on 3 ranks"
  [ "$(awk -F, 'NR > 1 { print $1 }' "$dir/out/stats.csv" | sort -u | tr -d '\n')" = 012 ] || fail "stats lack a rank"
fi
"$root/launch/demo" --frames 0 "$dir/x" >/dev/null 2>&1 && fail "--frames 0 accepted"
echo "ok"
