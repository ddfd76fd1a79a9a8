# SPDX-License-Identifier: MIT
# Helpers of the window tests (cli_window.sh, mpi_window.sh), sourced, and handed into the
# xvfb-run shell with `declare -f`. They read $dir/stdout and $pid of the caller's drive().

# Waits up to $2 seconds (a fraction allowed) for a stdout line matching $1 while the window runs.
await() {
  local i
  for ((i = 0; i < ${2%.*} * 20 + 10; ++i)); do
    grep -q -- "$1" "$dir/stdout" && return 0
    kill -0 $pid 2>/dev/null || break
    sleep 0.05
  done
  grep -q -- "$1" "$dir/stdout" && return 0
  echo "no stdout line '$1' after $2 s"
  return 1
}

# Presses Escape and waits up to 10 s for the window's process to end; prints "exit STATUS".
quit_window() {
  local i status
  xdotool key Escape
  for ((i = 0; i < 200; ++i)); do
    kill -0 $pid 2>/dev/null || break
    sleep 0.05
  done
  kill -0 $pid 2>/dev/null && { echo "still running 10 s after Escape"; return 1; }
  wait $pid
  status=$?
  echo "exit $status"
}
