#!/bin/sh
# UNet against PyTorch CPU, one command (`make bench-unet`): for each width (default 16 and 64) and
# each row (eval forward batch 1, train step batch 1, train step batch 4) run bench_unet and then
# benchmarks/peer_unet_torch.py on the same row, back to back, so both see the same machine state;
# then print one table: row, our ms, torch ms, ratio (ours / torch), our GFLOP/s, our device
# memory (and torch's peak RSS, its CPU analogue). Each side: minimum over REPS timed passes after
# one warm-up, torch with torch.set_num_threads(os.cpu_count()).
# The eval rows also run the inference-engine peers (benchmarks/peer_unet_onnx.py: the torch
# peer's model exported to ONNX, run by ONNX Runtime and OpenVINO on the CPU with all cores) and a
# second table gives ours / each engine. The engines are pip-installed into a virtual environment
# (PEER_VENV, default BUILD/peer-venv, with the system site packages for torch and numpy) on the
# first run; when that fails (no network, no venv module) they are skipped with a message.
#
#   sh benchmarks/unet_vs_torch.sh [BUILD]      env: WIDTHS ("16 64"), SIZE (308x410),
#                                                    REPS16 (3), REPS64 (2), PYTHON (/usr/bin/python3),
#                                                    ROWS ("eval 1;train 1;train 4"), PEER_VENV,
#                                                    ENGINES (onnxruntime,openvino; empty: none)
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
ROWS=${ROWS:-eval 1;train 1;train 4}
PEER_VENV=${PEER_VENV:-$BUILD/peer-venv}
ENGINES=${ENGINES-onnxruntime,openvino}
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

# inference-engine peers: a venv with onnxruntime and openvino (created once, reused)
engines=""
if [ $peer = 1 ] && [ -n "$ENGINES" ]; then
  vpy="$PEER_VENV/bin/python"
  if ! "$vpy" -c "import onnxruntime, openvino" 2>/dev/null; then
    echo "installing the ONNX Runtime and OpenVINO peers into $PEER_VENV (pip) ..." >&2
    { "$PYTHON" -m venv --system-site-packages "$PEER_VENV" &&
      "$vpy" -m pip install -q onnxruntime openvino; } >"$BUILD/peer-venv.log" 2>&1 || true
  fi
  for e in $(echo "$ENGINES" | tr ',' ' '); do
    if "$vpy" -c "import $e" 2>/dev/null; then
      engines="${engines:+$engines,}$e"
    else
      echo "$e peer skipped: cannot install or import it in $PEER_VENV (see $BUILD/peer-venv.log)" | tee -a "$RAW"
    fi
  done
fi

{
  echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "cpu: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores"
  if command -v clinfo >/dev/null 2>&1; then
    echo "opencl: $(clinfo 2>/dev/null | sed -n 's/^ *Platform Version *//p' | head -n 1)"
  fi
  [ $peer = 1 ] && echo "torch: $("$PYTHON" -c 'import torch; print(torch.__version__)')"
  [ -n "$engines" ] && echo "engines: $("$vpy" -c 'import onnxruntime as o, openvino as v; print("onnxruntime", o.__version__, "openvino", v.__version__)' 2>/dev/null)"
  echo "size: $SIZE; reps: width 16 -> $REPS16, width 64 -> $REPS64, others -> $REPS16 (minimum after one warm-up)"
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
} | tee -a "$RAW"

for wd in $WIDTHS; do
  reps=$REPS16
  [ "$wd" = 64 ] && reps=$REPS64
  echo "$ROWS" | tr ';' '\n' | while read -r r; do
    [ -n "$r" ] || continue
    set -- $r
    if [ "$1" = eval ]; then flags="--no-train --eval-batch $2"; else flags="--no-eval --batch $2"; fi
    echo "== width $wd, $1 batch $2 (load $(cut -d' ' -f1 /proc/loadavg))" | tee -a "$RAW"
    "$BENCH" --width "$wd" --size "$SIZE" --reps "$reps" $flags </dev/null | tee -a "$RAW"
    if [ $peer = 1 ]; then
      "$PYTHON" "$HERE/peer_unet_torch.py" --width "$wd" --size "$SIZE" --reps "$reps" $flags </dev/null | tee -a "$RAW"
    fi
    if [ "$1" = eval ] && [ -n "$engines" ]; then
      "$vpy" "$HERE/peer_unet_onnx.py" --width "$wd" --size "$SIZE" --reps "$reps" --eval-batch "$2" \
        --engines "$engines" --onnx out/bench </dev/null | tee -a "$RAW"
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
    else if (kv["impl"] == "torch") { theirs[key] = kv["ms"]; rss[key] = kv["mem_bytes"] }
    else if (kv["impl"] == "onnxruntime") ort[key] = kv["ms"]
    else if (kv["impl"] == "openvino") ovn[key] = kv["ms"]
  }
  END {
    printf "| %-14s | %10s | %10s | %6s | %11s | %14s | %15s |\n", "row", "ours ms", "torch ms", "ratio", "our GFLOP/s", "our device MiB", "torch maxrss MiB"
    printf "|%s|%s|%s|%s|%s|%s|%s|\n", "----------------", "-----------:", "-----------:", "-------:", "------------:", "---------------:", "-----------------:"
    for (i = 1; i <= n; i++) {
      k = order[i]
      t = (k in theirs) ? sprintf("%.1f", theirs[k]) : "-"
      ra = (k in theirs && theirs[k] > 0 && ours[k] > 0) ? sprintf("%.2f", ours[k] / theirs[k]) : "-"
      rm = (k in rss) ? sprintf("%.0f", rss[k] / 1048576) : "-"
      printf "| %-14s | %10.1f | %10s | %6s | %11.1f | %14.0f | %16s |\n", k, ours[k], t, ra, gfs[k], mem[k] / 1048576, rm
      # the goals: width 64 at most 0.6x PyTorch's time in eval, 0.8x in training (this run's times)
      if (k ~ /^w64 / && (k in theirs)) {
        goal = (k ~ / eval /) ? 0.6 : 0.8
        if (!(ours[k] > 0)) verdict[++nv] = sprintf("goal %s: ours did not run (see the raw output): MISSED", k)
        else verdict[++nv] = sprintf("goal %s: ours/torch %.2f vs <= %.1f: %s", k, ours[k] / theirs[k], goal,
                                     ours[k] / theirs[k] <= goal ? "HOLDS" : "MISSED")
        if (k == "w64 train b4" && ours[k] > 0 && rss[k] > 0)
          verdict[++nv] = sprintf("goal %s memory: our device bytes / torch peak RSS %.2f vs <= 1.0: %s", k,
                                  mem[k] / rss[k], mem[k] / rss[k] <= 1.0 ? "HOLDS" : "MISSED")
      }
    }
    for (i = 1; i <= nv; i++) print verdict[i]
    ne = 0
    for (i = 1; i <= n; i++) if ((order[i] in ort) || (order[i] in ovn)) ne++
    if (ne) {
      print ""
      print "Eval forward against the inference engines (ms: minimum; ratio = ours / engine)"
      printf "| %-11s | %8s | %8s | %14s | %11s | %10s | %10s | %10s |\n", "row", "ours ms", "torch ms", "onnxruntime ms", "openvino ms", "ours/torch", "ours/ORT", "ours/OV"
      printf "|%s|%s|%s|%s|%s|%s|%s|%s|\n", "-------------", "---------:", "---------:", "---------------:", "------------:", "-----------:", "-----------:", "-----------:"
      for (i = 1; i <= n; i++) {
        k = order[i]
        if (!((k in ort) || (k in ovn))) continue
        printf "| %-11s | %8.1f | %8s | %14s | %11s | %10s | %10s | %10s |\n", k, ours[k],
               (k in theirs) ? sprintf("%.1f", theirs[k]) : "-", (k in ort) ? sprintf("%.1f", ort[k]) : "-",
               (k in ovn) ? sprintf("%.1f", ovn[k]) : "-",
               (k in theirs) ? sprintf("%.2f", ours[k] / theirs[k]) : "-",
               (k in ort) ? sprintf("%.2f", ours[k] / ort[k]) : "-", (k in ovn) ? sprintf("%.2f", ours[k] / ovn[k]) : "-"
        if ((k == "w64 eval b1" || k == "w16 eval b1") && (k in ovn) && ovn[k] > 0 && ours[k] > 0) {
          goal = (k ~ /^w64/) ? 0.9 : 1.0
          ev[++ne2] = sprintf("goal %s: ours/OpenVINO %.2f vs <= %.1f: %s", k, ours[k] / ovn[k], goal,
                              ours[k] / ovn[k] <= goal ? "HOLDS" : "MISSED")
        }
      }
      for (i = 1; i <= ne2; i++) print ev[i]
    }
  }' "$RAW" | tee -a "$RAW"
