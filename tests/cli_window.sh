#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# occswitch render opens a GLFW window: under xvfb-run, real key presses sent with xdotool switch
# the mode, record the camera while W is held, freeze culling, take screenshots and quit with
# Escape; the screenshots are real pictures and the recorded path plays back. Without an X
# display the window fails with one error line and exit status 1.
set -u
export TESTS_DIR; TESTS_DIR=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=window_support.sh
. "$TESTS_DIR/window_support.sh"
exe=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
for tool in xvfb-run xdotool python3; do
  command -v $tool >/dev/null || fail "$tool is missing (launch/setup installs it)"
done
"$exe" gen plant --objects 300 -o "$dir/p.glb" 2>/dev/null || fail "gen"
"$exe" prep "$dir/p.glb" -o "$dir/p.oss" 2>/dev/null || fail "prep"

# No X display: one error line that points to --headless and xvfb-run, exit status 1.
timeout 30 env -u DISPLAY -u WAYLAND_DISPLAY "$exe" render "$dir/p.oss" --size 320x240 >"$dir/stdout" 2>"$dir/stderr"
status=$?
[ $status -eq 1 ] || fail "no display: exit $status, stderr: $(cat "$dir/stderr")"
[ "$(wc -l <"$dir/stderr")" -eq 1 ] && grep -q "^error: window: .*xvfb-run.*--headless" "$dir/stderr" ||
  fail "no display: stderr: $(cat "$dir/stderr")"
[ ! -s "$dir/stdout" ] || fail "no display: stdout: $(cat "$dir/stdout")"

# Runs inside xvfb-run: starts the window, types at it, waits for it to quit. Every wait is
# bounded, so xvfb-run always gets to stop its server.
drive() {
  local exe=$1 dir=$2 pid win status i
  "$exe" render "$dir/p.oss" --out "$dir/out" --size 320x240 >"$dir/stdout" 2>"$dir/stderr" &
  pid=$!
  trap 'kill -9 $pid 2>/dev/null' EXIT
  win=$(timeout 20 xdotool search --sync --name '^occswitch' | head -n 1)
  [ -n "$win" ] || { echo "no occswitch window after 20 s"; return 1; }
  await "^window: 320x240" 20 || return 1
  # No window manager: give the window the keyboard focus; xdotool then types through XTEST.
  xdotool windowfocus --sync "$win" || { echo "xdotool windowfocus $win failed"; return 1; }
  xdotool key 2 && await "^window: mode lod$" 10 || return 1
  xdotool key 3 && await "^window: mode oc+lod$" 10 || return 1
  xdotool key r && await "^window: recording$" 10 || return 1
  xdotool keydown w && sleep 0.5 && xdotool keyup w
  xdotool key r && await "^window: recorded " 10 || return 1
  xdotool key f && await "^window: culling frozen$" 10 || return 1
  xdotool key p && await "^window: screenshot .*screenshot_0.png$" 10 || return 1
  xdotool keydown d && sleep 0.5 && xdotool keyup d
  xdotool key p && await "^window: screenshot .*screenshot_1.png$" 10 || return 1
  xdotool key f && await "^window: culling live$" 10 || return 1
  xdotool key p && await "^window: screenshot .*screenshot_2.png$" 10 || return 1
  quit_window
}
timeout 90 xvfb-run -a -s "-screen 0 1024x768x24" bash -c "$(declare -f drive await quit_window); drive \"\$@\"" drive "$exe" "$dir" \
  >"$dir/drive" 2>&1
status=$?
[ $status -eq 0 ] && [ "$(tail -n 1 "$dir/drive")" = "exit 0" ] ||
  fail "window (xvfb-run status $status): $(cat "$dir/drive")
stdout: $(cat "$dir/stdout")
stderr: $(cat "$dir/stderr")"
out=$(cat "$dir/stdout")

grep -q "^window: 320x240, .*; keys: " <<<"$out" || fail "no start line: $out"
[ "$(grep -c "^window: " <<<"$out")" -eq "$(wc -l <<<"$out")" ] || fail "stdout line without 'window: ': $out"
# The recorded path: N > 0 poses, a camera path file that plays back.
line=$(grep "^window: recorded " <<<"$out")
[[ $line =~ ^window:\ recorded\ ([0-9]+)\ poses\ to\ (.*/recorded_0\.cam)$ ]] || fail "recorded line: $line"
poses=${BASH_REMATCH[1]} cam=${BASH_REMATCH[2]}
[ "$poses" -gt 0 ] || fail "recorded $poses poses"
[ "$cam" -ef "$dir/out/recorded_0.cam" ] || fail "recorded to $cam, not into --out"
[ "$(wc -l <"$cam")" -eq $((poses + 1)) ] || fail "$cam: $(wc -l <"$cam") lines for $poses poses"
"$exe" render "$dir/p.oss" --path "$cam" --no-display >"$dir/play" 2>&1 || fail "playing $cam: $(cat "$dir/play")"
grep -q "^render: .* $poses frames at " "$dir/play" || fail "playing $cam: $(cat "$dir/play")"
# The recording moved forward: the first and last eyes differ.
[ "$(sed -n 2p "$cam" | cut -d' ' -f1-3)" != "$(tail -n 1 "$cam" | cut -d' ' -f1-3)" ] || fail "W did not move the camera"

# Screenshots: 320x240 RGB, not the empty background. 0 and 1 are frozen, before and after moving
# with D; 1 shows the culling boxes (red: occlusion-culled, purple: occluders) that the live one (2),
# taken from the same place, lacks.
# Prints: width height distinct_colours background_share box_pixels.
png_stats() {
  python3 - "$1" <<'EOF'
import os, sys
sys.path.insert(0, os.environ["TESTS_DIR"])
from png_rgb import read_png_rgb
w, h, rows = read_png_rgb(sys.argv[1])
stride = 3 * w
pixels = [row[i:i + 3] for row in rows for i in range(0, stride, 3)]
near = lambda p, q: all(abs(u - v) <= 2 for u, v in zip(p, q))
background = sum(near(p, (20, 23, 28)) for p in pixels)
boxes = sum(near(p, (242, 38, 26)) or near(p, (179, 51, 242)) for p in pixels)
print(w, h, len(set(pixels)), "%.3f" % (background / len(pixels)), boxes)
EOF
}
for n in 0 1 2; do
  png=$dir/out/screenshot_$n.png
  grep -q "^window: screenshot $png$" <<<"$out" || fail "no screenshot line for $png: $out"
  [ -f "$png" ] || fail "$png missing"
  read -r w h colours background boxes[$n] < <(png_stats "$png") || fail "$png: not a readable PNG"
  [ "$w"x"$h" = 320x240 ] || fail "$png is ${w}x$h"
  [ "$colours" -ge 16 ] || fail "$png has $colours colours"
  awk "BEGIN { exit !($background < 0.98) }" || fail "$png is ${background} background"
done
cmp -s "$dir/out/screenshot_0.png" "$dir/out/screenshot_1.png" && fail "D did not move the camera over the frozen frame"
cmp -s "$dir/out/screenshot_1.png" "$dir/out/screenshot_2.png" && fail "the frozen and the live screenshot are the same"
[ "${boxes[1]}" -gt "${boxes[2]}" ] || fail "no culling boxes in the frozen screenshot: ${boxes[1]} box pixels, live ${boxes[2]}"
echo ok
