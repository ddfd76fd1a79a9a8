#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# usage: check_bad_input.sh OCCSWITCH FILE WORDS
# Passes when `occswitch info FILE` exits 2, prints nothing on stdout, and prints exactly one
# stderr line that starts with "error: FILE:" and contains WORDS (case-insensitive).
set -u
exe=$1 file=$2 words=$3
out=$(mktemp) err=$(mktemp)
trap 'rm -f "$out" "$err"' EXIT
timeout 30 "$exe" info "$file" >"$out" 2>"$err"
status=$?
fail() { echo "FAIL: $file: $*"; echo "--- stderr:"; cat "$err"; exit 1; }
[ "$status" -eq 2 ] || fail "exit status $status, expected 2"
[ -s "$out" ] && fail "printed on stdout"
[ "$(wc -l <"$err")" -eq 1 ] || fail "stderr has $(wc -l <"$err") lines, expected 1"
grep -q "^error: $(printf '%s' "$file" | sed 's/[][\.*^$]/\\&/g'): " "$err" || fail "stderr does not start with 'error: $file: '"
# the words must be in the message itself, not in the file name that prefixes it
message=$(cut -c$((${#file} + 10))- "$err")
printf '%s' "$message" | grep -qiF -- "$words" || fail "message '$message' lacks '$words'"
echo "ok: $(cat "$err")"
