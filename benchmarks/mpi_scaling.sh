#!/bin/bash
# Data-parallel training throughput on this machine: `smplpix train` on 1 process against
# `mpirun -np 2 smplpix train` (same data, global batch, steps), plus the gradient all-reduce alone.
#   benchmarks/mpi_scaling.sh [BUILD_DIR]  (env: NP=2 STEPS=12 WIDTH=16 BATCH=4 SIZE=128x96 OUT=out/mpi-scaling)
# Prints a Markdown table: images/s as the tool reports it at the last step (rank 0's clock, from the
# first step on; start-up excluded) and the efficiency against the 1-process run(s). PoCL runs one
# worker thread per core by default: with 2 ranks on a 2-core machine each rank is given one
# (POCL_MAX_PTHREAD_COUNT=1), and the 2-rank run is also timed with PoCL's default (oversubscribed).
set -euo pipefail
BUILD=${1:-build}
NP=${NP:-2} STEPS=${STEPS:-12} WIDTH=${WIDTH:-16} BATCH=${BATCH:-4} SIZE=${SIZE:-128x96} OUT=${OUT:-out/mpi-scaling}
T=$BUILD/smplpix
command -v mpirun >/dev/null || { echo "mpi_scaling: no mpirun (install openmpi-bin)" >&2; exit 1; }
MPI=(mpirun -q --oversubscribe --mca btl self,vader)
[ "$(id -u)" = 0 ] && MPI+=(--allow-run-as-root)
mkdir -p "$OUT"
if [ ! -d "$OUT/data/train" ]; then
  "$T" dataset --mesh data/body/human_woman.obj --out "$OUT/data" --orbit 24 --size "$SIZE" --split 1,0,0 --quiet --force
fi
ARGS=(train --data "$OUT/data" --width "$WIDTH" --batch "$BATCH" --steps "$STEPS" --log-every "$STEPS")
"$T" "${ARGS[@]}" --steps 1 --out "$OUT/warm.safetensors" >/dev/null 2>&1 # compile / load the kernels once

ips() { grep "^step $STEPS/$STEPS " "$1" | tail -1 | sed -E 's/.*, ([0-9.e+]+) images\/s.*/\1/'; }
run() { # label threads np
  local log="$OUT/$1.log" env=()
  [ "$2" != default ] && env=(env POCL_MAX_PTHREAD_COUNT="$2")
  if [ "$3" = 1 ]; then "${env[@]}" "$T" "${ARGS[@]}" --out "$OUT/$1.safetensors" >/dev/null 2>"$log"
  else "${env[@]}" "${MPI[@]}" -x POCL_MAX_PTHREAD_COUNT -np "$3" "$T" "${ARGS[@]}" --out "$OUT/$1.safetensors" >/dev/null 2>"$log"
  fi
  ips "$log"
}
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; width $WIDTH, global batch $BATCH, $SIZE, $STEPS steps"
export POCL_MAX_PTHREAD_COUNT=${POCL_MAX_PTHREAD_COUNT:-}
one_all=$(run r1_default default 1)
one_1t=$(run r1_1thread 1 1)
two_1t=$(run rN_1thread 1 "$NP")
two_all=$(run rN_default default "$NP")
echo
echo "| processes | PoCL threads each | images/s | vs 1 process, same threads each | vs 1 process, all cores |"
echo "|---|---|---|---|---|"
awk -v a="$one_all" -v b="$one_1t" -v c="$two_1t" -v d="$two_all" -v n="$NP" 'BEGIN {
  printf "| 1 | all (%s) | %.2f | - | 1.00 |\n", "default", a
  printf "| 1 | 1 | %.2f | 1.00 | %.2f |\n", b, b / a
  printf "| %d | 1 | %.2f | %.2f (efficiency %.0f%%) | %.2f |\n", n, c, c / b, 100 * c / b / n, c / a
  printf "| %d | all (default) | %.2f | - | %.2f |\n", n, d, d / a }'
echo
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
if [ -x "$BUILD/benchmarks/allreduce_mpi" ]; then
  echo; echo "gradient all-reduce alone (apps/comm_mpi.c), $NP ranks:"
  "${MPI[@]}" -np "$NP" "$BUILD/benchmarks/allreduce_mpi" 5
fi
