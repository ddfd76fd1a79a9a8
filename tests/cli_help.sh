#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# --help of the command and of every subcommand exits 0 and names what it does.
set -eu
exe=$1
"$exe" --help | grep -q "info"
"$exe" --help | grep -q "gen"
"$exe" info --help | grep -q "JSON"
"$exe" gen grid --help | grep -q -- "--nx"
"$exe" gen plant --help | grep -q -- "--objects"
"$exe" --version | grep -q "occswitch"
echo ok
