#!/bin/sh
# UNet against PyTorch CPU, one command (`make bench-unet`): for each width (default 16 and 64) and
# each row (eval forward batch 1, train step batch 1, train step batch 4) run bench_unet and then
# benchmarks/peer_unet_torch.py on the same row, back to back, so both see the same machine state;
# then print one table: row, our ms, torch ms, ratio (ours / torch), our GFLOP/s, our device
# memory (and torch's peak RSS, its CPU analogue). Each side: minimum over REPS timed passes after
# one warm-up, torch with torch.set_num_threads(os.cpu_count()).
#
#   sh benchmarks/unet_vs_torch.sh [BUILD]      env: WIDTHS ("16 64"), SIZE (308x410),
#                                                    REPS16 (3), REPS64 (2), PYTHON (/usr/bin/python3)
# Width 64 uses 2 reps by default to keep the whole run near 10 minutes on a 2-core CPU.
# Without PyTorch the peer is skipped (said so) and the torch columns read "-".
# Raw output: out/bench/unet_vs_torch.txt.
set -eu
BUILD=${1:-build}
HERE=$(cd "$(dirname "$0")" && pwd)
WIDTHS=${WIDTHS:-16 64}
SIZE=${SIZE:-308x410}
REPS16=${REPS16:-3}
REPS64=${REPS64:-2}
PYTHON=${PYTHON:-/usr/bin/python3}
BENCH="$BUILD/benchmarks/bench_unet"
[ -x "$BENCH" ] || { echo "unet_vs_torch.sh: $BENCH not built (make build)" >&2; exit 1; }
mkdir -p out/bench
RAW=out/bench/unet_vs_torch.txt
: > "$RAW"

peer=1
if ! "$PYTHON" -c "import torch" 2>/dev/null; then
  peer=0
  echo "torch peer skipped: $PYTHON cannot import torch (apt install python3-torch)" | tee -a "$RAW"
fi

{
  echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "cpu: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores"
  if command -v clinfo >/dev/null 2>&1; then
    echo "opencl: $(clinfo 2>/dev/null | sed -n 's/^ *Platform Version *//p' | head -n 1)"
  fi
  [ $peer = 1 ] && echo "torch: $("$PYTHON" -c 'import torch; print(torch.__version__)')"
  echo "size: $SIZE; reps: width 16 -> $REPS16, width 64 -> $REPS64, others -> $REPS16 (minimum after one warm-up)"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee -a "$RAW"

for wd in $WIDTHS; do
  reps=$REPS16
  [ "$wd" = 64 ] && reps=$REPS64
  for r in "eval 1" "train 1" "train 4"; do
    set -- $r
    if [ "$1" = eval ]; then flags="--no-train --eval-batch $2"; else flags="--no-eval --batch $2"; fi
    echo "== width $wd, $1 batch $2 (load $(cut -d' ' -f1 /proc/loadavg))" | tee -a "$RAW"
    "$BENCH" --width "$wd" --size "$SIZE" --reps "$reps" $flags | tee -a "$RAW"
    if [ $peer = 1 ]; then
      "$PYTHON" "$HERE/peer_unet_torch.py" --width "$wd" --size "$SIZE" --reps "$reps" $flags | tee -a "$RAW"
    fi
  done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$RAW"

echo
echo "UNet at 4x$SIZE (ms: minimum; ratio = ours / torch; GFLOP/s: 2 x conv multiply-adds, train = 3x forward)"
awk '
  /^ROW / {
    delete kv
    for (i = 2; i <= NF; i++) { split($i, p, "="); kv[p[1]] = p[2] }
    key = "w" kv["width"] " " kv["mode"] " b" kv["batch"]
    if (!(key in seen)) { seen[key] = 1; order[++n] = key }
    if (kv["impl"] == "smplpix") { ours[key] = kv["ms"]; gfs[key] = kv["gflops"]; mem[key] = kv["mem_bytes"] }
    else { theirs[key] = kv["ms"]; rss[key] = kv["mem_bytes"] }
  }
  END {
    printf "| %-14s | %10s | %10s | %6s | %11s | %14s | %15s |\n", "row", "ours ms", "torch ms", "ratio", "our GFLOP/s", "our device MiB", "torch maxrss MiB"
    printf "|%s|%s|%s|%s|%s|%s|%s|\n", "----------------", "-----------:", "-----------:", "-------:", "------------:", "---------------:", "-----------------:"
    for (i = 1; i <= n; i++) {
      k = order[i]
      t = (k in theirs) ? sprintf("%.1f", theirs[k]) : "-"
      ra = (k in theirs && theirs[k] > 0 && k in ours) ? sprintf("%.2f", ours[k] / theirs[k]) : "-"
      rm = (k in rss) ? sprintf("%.0f", rss[k] / 1048576) : "-"
      printf "| %-14s | %10.1f | %10s | %6s | %11.1f | %14.0f | %16s |\n", k, ours[k], t, ra, gfs[k], mem[k] / 1048576, rm
      if (k ~ /^w64 / && (k in theirs)) {
        goal = (k ~ / eval /) ? 1.5 : 2.0
        verdict[++nv] = sprintf("goal %s: ours/torch %.2f vs <= %.1f: %s", k, ours[k] / theirs[k], goal,
                                ours[k] / theirs[k] <= goal ? "HOLDS" : "MISSED")
      }
    }
    for (i = 1; i <= nv; i++) print verdict[i]
  }' "$RAW" | tee -a "$RAW"
