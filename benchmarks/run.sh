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
  if [ "$name" = bench_clblast ]; then # a GPU baseline (the device kit's first step): hours of PoCL at full size
    echo "== bench_clblast skipped (CLBlast's convolutions on the UNet shapes: run it alone, e.g. bench_clblast 1 --div 8)"
    continue
  fi
  echo "== $name"
  "$b" | tee "out/bench/$name.txt"
done
# The Python binding's per-call overhead (needs python3 with numpy; skipped, saying so, otherwise)
if /usr/bin/python3 -c "import numpy" >/dev/null 2>&1; then
  echo "== python_overhead"
  /usr/bin/python3 "$HERE/python_overhead.py" "$BUILD" | tee out/bench/python_overhead.txt
else
  echo "== python_overhead skipped: /usr/bin/python3 with numpy not found"
fi
