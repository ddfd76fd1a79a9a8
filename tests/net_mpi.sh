#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The MPI transport's fault guarantees across three real ranks (docs/protocol.md, "Faults").
#   net_mpi.sh PROBE none     all ranks exit 0 and print "ok rank R"
#   net_mpi.sh PROBE kill     rank 1 SIGKILLs itself at frame 20
#   net_mpi.sh PROBE hang     rank 1 stops answering at frame 20
#   net_mpi.sh PROBE garbage  rank 1 sends a corrupted delta at frame 20
#   net_mpi.sh PROBE MODE tcp the same over Open MPI's TCP transport on 127.0.0.1 (shared
#                             memory off), as between nodes
# After a fault, both other ranks must print "error: rank 1: ..." (the culprit, whoever noticed
# it) within 10 s of the launch (the fault comes at frame 5, a fraction of a second in), and
# mpirun must end non-zero within 20 s (it SIGKILLs a hung rank only after the 3 s grace).
# Over TCP a killed or hung rank leaves the survivors blocked inside Open MPI (its TCP transport
# retries the dead peer's socket and prints a help message) where no error of ours can be
# raised: there mpirun's own teardown is the bound (about 6.5 s after a kill, 10 s after a hang
# on this machine), and the test asserts only that bound, a non-zero exit, no "ok" and no
# healthy rank blamed (docs/protocol.md, "Faults over TCP").
set -u
probe=$1
mode=$2
transport=${3:-sm}
mca=()
[ "$transport" = tcp ] && mca=(--mca pml ob1 --mca btl tcp,self --mca btl_tcp_if_include lo)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
out=$(mktemp)
trap 'rm -f "$out"' EXIT

start=$(date +%s%N)
# Each output line is stamped with the milliseconds since launch when it arrived.
# odls_base_sigkill_timeout 3: see docs/protocol.md, "Faults" (1 s is too short on a loaded machine).
timeout 20 mpirun -np 3 --oversubscribe --mca odls_base_sigkill_timeout 3 "${mca[@]}" "$probe" --frames 60 --frame-ms 10 \
    --timeout-ms 3000 --fault "$mode" --fault-rank 1 --fault-frame 5 2>&1 |
    while IFS= read -r line; do echo "$((($(date +%s%N) - start) / 1000000)) $line"; done >"$out"
status=${PIPESTATUS[0]}
elapsed_ms=$((($(date +%s%N) - start) / 1000000))
echo "mode $mode ($transport): mpirun exit status $status after $elapsed_ms ms"
grep -E '^[0-9]+ (ok|error)' "$out"

fail() {
    echo "FAIL: $*"
    cat "$out"
    exit 1
}

[ "$status" -ne 124 ] || fail "mpirun still running after 20 s"
if [ "$mode" = none ]; then
    [ "$status" -eq 0 ] || fail "a normal run exited with status $status"
    [ "$(grep -c '^[0-9]* ok rank' "$out")" -eq 3 ] || fail "not every rank reported ok"
    ! grep -q '^[0-9]* error' "$out" || fail "a normal run printed an error"
    exit 0
fi
[ "$status" -ne 0 ] || fail "mpirun exited 0 after a $mode fault"
! grep -q '^[0-9]* ok rank' "$out" || fail "a rank finished although the run failed"
! grep -E '^[0-9]+ error: rank [02]: ' "$out" || fail "a healthy rank was blamed"
if [ "$transport" = tcp ] && [ "$mode" != garbage ]; then
    echo "over TCP: mpirun ended the job $elapsed_ms ms after the launch; $(grep -c '^[0-9]* error: rank 1:' "$out") survivors named rank 1"
    exit 0
fi
# The lines do not say which rank printed them; one per surviving rank is what is counted.
culprit_lines=$(awk '$2 == "error:" && $3 == "rank" && $4 == "1:" && $1 <= 10000' "$out" | wc -l)
[ "$culprit_lines" -ge 2 ] || fail "expected both surviving ranks to print 'error: rank 1: ...' within 10 s, got $culprit_lines"
! grep -E '^[0-9]+ error: rank [02]: ' "$out" || fail "a healthy rank was blamed"
! grep -q '^[0-9]* ok rank' "$out" || fail "a rank finished although the run failed"
exit 0
