#!/bin/sh
# Run every benchmark executable in BUILD/benchmarks (and the PyTorch peers when torch is present).
# Output: a table per benchmark on stdout and a copy under out/bench/.
set -eu
BUILD=${1:-build}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p out/bench
for b in "$BUILD"/benchmarks/bench_*; do
  [ -x "$b" ] || continue
  name=$(basename "$b")
  echo "== $name"
  "$b" | tee "out/bench/$name.txt"
done
