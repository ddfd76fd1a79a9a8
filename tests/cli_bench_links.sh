#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# bench links on a tiny sweep (3 ranks; no link, then 0 and 2 ms at 100 Mb/s; then the narrow
# link): links.md, links.csv and plots/links.png are written; every run keeps exactly one frame
# of camera-to-display latency; a camera crosses two links (display -> culler -> display), so
# the 2 ms link adds at least 4 ms to that latency's floor; the narrow link holds the frames shown
# to about what its bandwidth carries; bytes stay what the no-link run sends per frame within the
# poses it skips. Impossible options exit 2.
set -u
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
"$exe" gen plant --objects 300 -o "$dir/p.glb" 2>/dev/null || fail "gen"
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" --hierarchy off 2>/dev/null || fail "prep"
"$exe" bench links --out "$dir/b" --scene "$dir/p.oss" --layouts 3 --latencies 0,2 --mbps 100 --frames 20 \
  --path-fps 20 --saturate-fps 4 --size 160x120 >"$dir/out" 2>"$dir/err" || fail "bench links: $(tail -5 "$dir/err")"
[ "$(cat "$dir/out")" = "$dir/b/links.md" ] || fail "stdout: $(cat "$dir/out")"
[ -s "$dir/b/plots/links.png" ] || fail "no plots/links.png"
grep -q "^| 3 | none |" "$dir/b/links.md" || fail "links.md: $(cat "$dir/b/links.md")"
python3 - "$dir/b/links.csv" <<'PY' || fail "links.csv"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert [(r['latency_ms'], r['mbps'], r['saturating']) for r in rows] == [
    ('0.000', '0.000000', '0'), ('0.000', '100.000000', '0'), ('2.000', '100.000000', '0'), ('0.000', rows[3]['mbps'], '1')], rows
for r in rows:
    assert float(r['latency_frames']) == 1.0, f"{r['link']}: latency {r['latency_frames']} frames, not 1"
    assert int(r['frames_shown']) + int(r['poses_skipped']) == 20, r
    assert float(r['fps']) > 0 and float(r['bytes_total']) > 0 and float(r['switch_model_bytes']) > 0, r
    assert float(r['display_latency_ms']) > 0, r
floor = float(rows[0]['display_latency_ms'])
two_ms = float(rows[2]['display_latency_ms'])
assert two_ms >= 4.0, f'2 ms link: camera-to-display {two_ms} ms, not >= 4'
narrow = rows[3]
# The narrow link carries what 4 fps need of the unemulated run's bytes: far fewer frames than 20 fps.
assert 0 < float(narrow['mbps']) < 1, narrow
assert float(narrow['fps']) < 12, f"narrow link: {narrow['fps']} fps shown"
PY
status=0
"$exe" bench links --out "$dir/c" --scene "$dir/p.oss" --layouts 2 >/dev/null 2>"$dir/err" || status=$?
[ $status -eq 2 ] && grep -q "^error: bench links: --layouts 2" "$dir/err" || fail "--layouts 2: exit $status, $(cat "$dir/err")"
status=0
"$exe" bench links --out "$dir/c" --scene "$dir/p.oss" --mbps 0 >/dev/null 2>"$dir/err" || status=$?
[ $status -eq 2 ] && grep -q "^error: bench links: --mbps" "$dir/err" || fail "--mbps 0: exit $status, $(cat "$dir/err")"
echo ok
