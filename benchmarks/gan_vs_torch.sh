#!/bin/sh
# One stage-2 training step (UNet generator + 3-scale PatchGAN + frozen VGG19, Adam on G and D)
# against PyTorch CPU in the same run: bench_gan_step, then peer_gan_step_torch.py, back to back;
# prints both times and the ratio ours / torch. Raw output: out/bench/gan_vs_torch.txt.
#   sh benchmarks/gan_vs_torch.sh [BUILD]   env: WIDTH (64), DWIDTH (64), SIZE (308x410), REPS (2),
#                                                PYTHON (/usr/bin/python3)
set -eu
BUILD=${1:-build}
HERE=$(cd "$(dirname "$0")" && pwd)
WIDTH=${WIDTH:-64}
DWIDTH=${DWIDTH:-64}
SIZE=${SIZE:-308x410}
REPS=${REPS:-2}
PYTHON=${PYTHON:-/usr/bin/python3}
BENCH="$BUILD/benchmarks/bench_gan_step"
[ -x "$BENCH" ] || { echo "gan_vs_torch.sh: $BENCH not built" >&2; exit 1; }
mkdir -p out/bench
RAW=out/bench/gan_vs_torch.txt
{
  echo "date: $(date -u '+%Y-%m-%d %H:%M UTC'); cpu: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee "$RAW"
"$BENCH" --width "$WIDTH" --disc-width "$DWIDTH" --size "$SIZE" --reps "$REPS" | tee -a "$RAW"
if "$PYTHON" -c "import torch" 2>/dev/null; then
  "$PYTHON" "$HERE/peer_gan_step_torch.py" --width "$WIDTH" --disc-width "$DWIDTH" --size "$SIZE" --reps "$REPS" | tee -a "$RAW"
else
  echo "torch peer skipped: $PYTHON cannot import torch" | tee -a "$RAW"
fi
ours=$(sed -n 's/^ROW impl=smplpix .* ms=\([0-9.]*\).*/\1/p' "$RAW")
theirs=$(sed -n 's/^ROW impl=torch .* ms=\([0-9.]*\).*/\1/p' "$RAW")
if [ -n "$ours" ] && [ -n "$theirs" ]; then
  awk -v a="$ours" -v b="$theirs" 'BEGIN { printf "stage-2 step: ours %.0f ms, torch %.0f ms, ratio %.2f\n", a, b, a / b }' | tee -a "$RAW"
fi
