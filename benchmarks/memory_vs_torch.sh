#!/bin/sh
# Peak memory of the same work, ours against PyTorch CPU, one process per row and side, back to
# back (`make bench-memory`). Rows: width-64 UNet training step at batch 1 and 4, width-64 eval
# forward (batch 1), and the stage-2 GAN+VGG step (G width 64, 3 PatchGANs width 64, VGG19;
# batch 1). All 4x308x410 (SIZE). Each process runs one warm-up and REPS (1) timed passes.
#
# Ours: peak_bytes = the device-memory high-water mark of the row (spx_device_peak_bytes: every
# device buffer: parameter/gradient/Adam/state slabs, the activation arena, convolution workspace,
# per-call scratch); rss_bytes = the process's peak resident set (ru_maxrss; with PoCL the device
# memory is host memory, plus the OpenCL runtime, the LLVM kernel compiler and host-side inputs).
# Torch: mem_bytes = the peer's peak resident set (ru_maxrss: interpreter, torch libraries, model,
# optimizer state, inputs, autograd saved tensors, allocator caches).
# Table on stdout (markdown) and in out/bench/memory_vs_torch.txt with the raw ROW lines.
#   sh benchmarks/memory_vs_torch.sh [BUILD]   env: SIZE (308x410), REPS (1), PYTHON (/usr/bin/python3)
set -eu
BUILD=${1:-build}
HERE=$(cd "$(dirname "$0")" && pwd)
SIZE=${SIZE:-308x410}
REPS=${REPS:-1}
PYTHON=${PYTHON:-/usr/bin/python3}
UNET="$BUILD/benchmarks/bench_unet"
GAN="$BUILD/benchmarks/bench_gan_step"
for b in "$UNET" "$GAN"; do [ -x "$b" ] || { echo "memory_vs_torch.sh: $b not built" >&2; exit 1; }; done
TORCH=1
"$PYTHON" -c "import torch" 2>/dev/null || TORCH=0
mkdir -p out/bench
RAW=out/bench/memory_vs_torch.txt
{
  echo "date: $(date -u '+%Y-%m-%d %H:%M UTC'); cpu: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee "$RAW"
[ "$TORCH" = 1 ] || echo "torch peer skipped: $PYTHON cannot import torch" | tee -a "$RAW"

# one row: NAME, then our command line and the peer's (relative to benchmarks/)
run_row() {
  name=$1 ours=$2 peer=$3
  echo "row $name: load $(cut -d' ' -f1 /proc/loadavg)" | tee -a "$RAW"
  # shellcheck disable=SC2086
  $ours | sed -n "s/^ROW /ROW name=$name /p" | tee -a "$RAW"
  if [ "$TORCH" = 1 ]; then
    # shellcheck disable=SC2086
    "$PYTHON" $peer | sed -n "s/^ROW /ROW name=$name /p" | tee -a "$RAW"
  fi
}
COMMON="--width 64 --size $SIZE --reps $REPS"
run_row w64_train_b1 "$UNET $COMMON --no-eval --batch 1" "$HERE/peer_unet_torch.py $COMMON --no-eval --batch 1"
run_row w64_train_b4 "$UNET $COMMON --no-eval --batch 4" "$HERE/peer_unet_torch.py $COMMON --no-eval --batch 4"
run_row w64_eval_b1 "$UNET $COMMON --no-train --eval-batch 1" "$HERE/peer_unet_torch.py $COMMON --no-train --eval-batch 1"
run_row gan_vgg_step "$GAN --width 64 --disc-width 64 --size $SIZE --reps $REPS" \
  "$HERE/peer_gan_step_torch.py --width 64 --disc-width 64 --size $SIZE --reps $REPS"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$RAW"

echo
echo "| row | ours: device peak MiB | ours: process peak RSS MiB | torch: peak RSS MiB | device peak / torch RSS | our RSS / torch RSS |"
echo "|---|---:|---:|---:|---:|---:|"
awk '
  function field(k,   i, kv) { for (i = 1; i <= NF; i++) { split($i, kv, "="); if (kv[1] == k) return kv[2] } return "" }
  /^ROW / {
    n = field("name")
    if (!(n in seen)) { seen[n] = 1; order[++rows] = n }
    if (field("impl") == "smplpix") { peak[n] = field("peak_bytes"); rss[n] = field("rss_bytes") }
    else torch[n] = field("mem_bytes")
  }
  END {
    for (r = 1; r <= rows; r++) {
      n = order[r]; M = 1048576
      if (torch[n] != "")
        printf "| %s | %.0f | %.0f | %.0f | %.2f | %.2f |\n", n, peak[n] / M, rss[n] / M, torch[n] / M, peak[n] / torch[n], rss[n] / torch[n]
      else
        printf "| %s | %.0f | %.0f | - | - | - |\n", n, peak[n] / M, rss[n] / M
    }
  }' "$RAW" | tee -a "$RAW"
