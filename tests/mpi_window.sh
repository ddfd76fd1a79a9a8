#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# One window, many ranks: `mpirun -np 3 occswitch render S.oss` under xvfb-run opens exactly one
# window (rank 0, the display; ranks 1 and 2 are the occlusion switch), whose title shows the
# ranks and the latency; real key presses (xdotool) move the camera, so that two screenshots
# differ, freeze it, and Escape ends all three ranks with exit status 0 within 10 s. Every rank's
# rows reach --stats. With 5 ranks (the switch and 3 sort-last display ranks) the one window shows
# the composite, moves and ends the same way, and F says why it cannot freeze. A culling rank
# killed while the window runs ends every rank within 10 s, rank 0 naming it; one stopped for
# 2 s does not freeze the window (a key press still takes a screenshot meanwhile). Without an X
# display rank 0 fails and the culling ranks stop at once.
set -u
export TESTS_DIR; TESTS_DIR=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=window_support.sh
. "$TESTS_DIR/window_support.sh"
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
for tool in xvfb-run xdotool mpirun python3; do
  command -v $tool >/dev/null || fail "$tool is missing (launch/setup installs it)"
done
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
"$exe" gen plant --objects 300 -o "$dir/p.glb" 2>/dev/null || fail "gen"
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" 2>/dev/null || fail "prep"

# No X display: rank 0 cannot open its window; it says so and every rank is gone within 20 s.
start=$SECONDS
timeout 60 env -u DISPLAY -u WAYLAND_DISPLAY mpirun --oversubscribe -np 3 "$exe" render "$dir/p.oss" --size 160x120 \
  >"$dir/stdout" 2>"$dir/stderr"
status=$?
[ $status -ne 0 ] && [ $status -ne 124 ] || fail "no display, 3 ranks: exit $status"
[ $((SECONDS - start)) -le 20 ] || fail "no display, 3 ranks: $((SECONDS - start)) s to exit"
grep -q "^error: window: .*--headless" "$dir/stderr" || fail "no display, 3 ranks: stderr: $(cat "$dir/stderr")"

drive() {
  local exe=$1 dir=$2 n=$3 pid win wins status i title
  mpirun --oversubscribe -np $n "$exe" render "$dir/p.oss" --out "$dir/out" --size 320x240 --stats "$dir/s.csv" \
    >"$dir/stdout" 2>"$dir/stderr" &
  pid=$!
  trap 'kill -9 $pid 2>/dev/null' EXIT
  await "^window: 320x240, .*$n ranks" 60 || return 1
  win=$(timeout 20 xdotool search --sync --name '^occswitch' | head -n 1)
  [ -n "$win" ] || { echo "no occswitch window after 20 s"; return 1; }
  # A culling rank that opened a window would have done so by now.
  sleep 2
  wins=$(xdotool search --name '^occswitch' | wc -l)
  [ "$wins" -eq 1 ] || { echo "$wins occswitch windows, not 1"; return 1; }
  xdotool windowfocus --sync "$win" || { echo "xdotool windowfocus $win failed"; return 1; }
  xdotool key p && await "screenshot_0.png$" 10 || return 1
  xdotool keydown w && sleep 1 && xdotool keyup w
  sleep 0.5
  xdotool key p && await "screenshot_1.png$" 10 || return 1
  title=$(xdotool getwindowname "$win")
  echo "title: $title"
  xdotool key 2 && await "^window: the mode keys need one rank" 10 || return 1
  if [ $n -gt 3 ]; then
    xdotool key f && await "^window: F (freeze) needs 1 to 3 ranks" 10 || return 1
  else
    xdotool key f && await "^window: culling frozen$" 10 || return 1
  fi
  xdotool keydown d && sleep 0.5 && xdotool keyup d
  sleep 0.3
  xdotool key p && await "screenshot_2.png$" 10 || return 1
  # A culling rank that does not answer for a while (SIGSTOP, 2 s): the window still answers keys.
  local culler=
  for p in $(pgrep -f "occswitch render $dir/p.oss --out"); do
    tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=1" && culler=$p
  done
  [ -n "$culler" ] || { echo "rank 1 not found"; return 1; }
  kill -STOP "$culler"
  sleep 0.3
  xdotool key p
  await "screenshot_3.png$" 1.5 || { kill -CONT "$culler"; echo "the window did not answer while rank 1 was stopped"; return 1; }
  sleep 0.5
  kill -CONT "$culler"
  sleep 0.5
  quit_window
}
drive_kill() {
  local exe=$1 dir=$2 pid victim i status
  mpirun --oversubscribe --mca odls_base_sigkill_timeout 3 -np 3 "$exe" render "$dir/p.oss" --size 160x120 \
    >"$dir/kstdout" 2>"$dir/kstderr" &
  pid=$!
  trap 'kill -9 $pid 2>/dev/null' EXIT
  for ((i = 0; i < 600; ++i)); do grep -q "^window: 160x120" "$dir/kstdout" && break; sleep 0.1; done
  for p in $(pgrep -f "occswitch render $dir/p.oss --size 160x120"); do
    tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=2" && victim=$p
  done
  [ -n "${victim:-}" ] || { echo "rank 2 not found"; return 1; }
  sleep 1
  kill -9 "$victim"
  for ((i = 0; i < 100; ++i)); do kill -0 $pid 2>/dev/null || break; sleep 0.1; done
  kill -0 $pid 2>/dev/null && { echo "still running 10 s after rank 2 was killed"; return 1; }
  wait $pid
  echo "exit $?"
}
timeout 120 xvfb-run -a -s "-screen 0 1024x768x24" bash -c "$(declare -f drive_kill); drive_kill \"\$@\"" drive_kill \
  "$exe" "$dir" >"$dir/drive" 2>&1
status=$(tail -n 1 "$dir/drive")
[ "$status" != "exit 0" ] && [[ $status == exit* ]] || fail "window, rank 2 killed: $(cat "$dir/drive")"
grep -q "^error: rank 2: " "$dir/kstderr" || fail "window, rank 2 killed: rank 0 did not name it: $(cat "$dir/kstderr")"

for n in 3 5; do
  rm -rf "$dir/out" "$dir/s.csv"
  timeout 150 xvfb-run -a -s "-screen 0 1024x768x24" bash -c "$(declare -f drive await quit_window); drive \"\$@\"" drive "$exe" "$dir" $n \
    >"$dir/drive" 2>&1
  status=$?
  [ $status -eq 0 ] && [ "$(tail -n 1 "$dir/drive")" = "exit 0" ] ||
    fail "window on $n ranks (xvfb-run status $status): $(cat "$dir/drive")
stdout: $(cat "$dir/stdout")
stderr: $(cat "$dir/stderr")"
  out=$(cat "$dir/stdout")
  title=$(grep "^title: " "$dir/drive")
  [[ $title =~ occswitch\ \ [0-9.]+\ fps\ \ $n\ ranks\ \ latency\ [0-9]+\ frames?\ [0-9.]+\ ms\ \ [0-9]+\ visible\ objects ]] ||
    fail "$n ranks: window title: $title"
  line=$(grep "^window: [0-9]* frames on $n ranks, latency " <<<"$out") || fail "$n ranks: no end line: $out"
  frames=$(sed 's/^window: \([0-9]*\) frames.*/\1/' <<<"$line")
  [ "$frames" -ge 3 ] || fail "$n ranks: $frames frames: $line"
  # Every rank's rows: the display ranks' frames, and each culling rank's share of them.
  python3 - "$dir/s.csv" "$frames" "$n" <<'PY' || fail "$n ranks: stats of the window run"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
frames, n = int(sys.argv[2]), int(sys.argv[3])
displays = ["0"] + [str(r) for r in range(3, n)]
for d in displays:
    assert [int(x["frame"]) for x in rows if x["rank"] == d] == list(range(frames)), ("display frames", d)
per = {r: [int(x["frame"]) for x in rows if x["rank"] == r] for r in ("1", "2")}
assert sorted(per["1"] + per["2"]) == list(range(frames)), "culling ranks' frames"
assert all(f % 2 == 0 for f in per["1"]) and all(f % 2 == 1 for f in per["2"]), "the switch alternates"
assert all(x["role"] == "or+hc" for x in rows if x["rank"] in ("1", "2"))
PY
  for s in 0 1 2; do [ -s "$dir/out/screenshot_$s.png" ] || fail "$n ranks: screenshot_$s.png missing"; done
  cmp -s "$dir/out/screenshot_0.png" "$dir/out/screenshot_1.png" && fail "$n ranks: W did not move the picture"
  if [ $n -le 3 ]; then
    cmp -s "$dir/out/screenshot_1.png" "$dir/out/screenshot_2.png" && fail "D over the frozen frame did not move the picture"
  else
    cmp -s "$dir/out/screenshot_1.png" "$dir/out/screenshot_2.png" && fail "$n ranks: D did not move the picture"
  fi
  echo "ok: $line"
done
