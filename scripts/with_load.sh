#!/usr/bin/env bash
# Run a command with a stress-like CPU load beside it (as `stress --cpu N` would), to show that the
# tests' waits hold on a loaded machine:  bash scripts/with_load.sh 2 make test
# N busy processes (default: one per core) spin at the command's own priority; they end with it.
set -uo pipefail
n="${1:-$(nproc)}"; shift
[ $# -gt 0 ] || { echo "usage: scripts/with_load.sh N command [args...]" >&2; exit 2; }
pids=()
for _ in $(seq "$n"); do
  python3 -c 'while True: pass' &
  pids+=($!)
done
trap 'kill "${pids[@]}" 2>/dev/null' EXIT INT TERM
echo "with_load: $n busy process(es) beside: $*" >&2
start=$(date +%s)
"$@"
rc=$?
echo "with_load: exit $rc after $(( $(date +%s) - start )) s under a load of $n busy process(es)" >&2
exit $rc
