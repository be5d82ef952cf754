# Sourced by scripts/device/run.sh (bash): the kit's first step, "the first GPU minute explains the
# gap" (docs/gpu.md). Its sub-steps share FIRST_BUDGET seconds (default 90, x SPX_RUN_LIMIT_SCALE);
# one that would start with under 5 s of it left is skipped, saying so. In order of value:
#   first_devices  `smplpix devices --peak` on the device: the device list and the roofline
#   first_dump     `smplpix devices --warmup` with SPX_CL_DUMP_DIR: every program's source, options
#                  and, on NVIDIA, its compiled PTX (NAME.ptx); fills the program cache for the rest
#   first_mma      probe_cl mma: does NVIDIA's OpenCL compiler take inline PTX mma.sync ... tf32
#                  (scripts/device/mma_tf32_probe.cl), and is the result right
#   first_nvverbose  probe_cl build --nv-verbose of every conv2d*.cl / gemm*.cl program: NVIDIA's own
#                  ptxas figures (registers, spills, stack, shared memory) per kernel
#   first_eval, first_train  bench_unet at width UW, batch 1, eval and a training step apart, with
#                  SPX_KERNEL_PROFILE=1 (each kernel's device time) and SPX_TAPE_PROFILE=2 (each
#                  layer's time, FLOPs, bytes, share of the roofline)
#   first_conv     bench_conv2d: the UNet-64 layer shapes alone, forward / backward data / backward
#                  weights, with the roofline and SPX_KERNEL_PROFILE=1
#   first_clblast  bench_clblast: CLBlast's convgemm and im2col + GEMM on the same shapes
# Then $OUT/first.tgz (first/: programs/ with the PTX, nvverbose/, every sub-step's log; read here
# with scripts/device/analyse_ptx.sh $OUT) and the step's section of summary.txt, both written at
# once so they come back even if a later step is cut off.
# Needs from run.sh: step, say, SPX, B, DEV, W, LOG, OUT, SUM, ROOT, UW, USIZE, QUICK.

FIRST=$W/first
mkdir -p "$FIRST/programs" "$FIRST/nvverbose"
export FIRST

first_devices() { "$SPX" devices --peak --device "$DEV"; } # the list, then the roofline
first_dump() { SPX_CL_DUMP_DIR="$FIRST/programs" "$SPX" devices --warmup --device "$DEV"; }
first_mma() { "$B/probe_cl" mma "$ROOT/scripts/device/mma_tf32_probe.cl"; }
first_nvverbose() {
  local f n=0
  for f in "$FIRST"/programs/conv2d*.cl "$FIRST"/programs/gemm*.cl; do
    [ -f "$f" ] || continue
    "$B/probe_cl" build "$f" --opts-file "$f.opts" --nv-verbose >"$FIRST/nvverbose/$(basename "$f" .cl).log" 2>&1
    n=$((n + 1))
  done
  echo "$n programs built again with -cl-nv-verbose (NVIDIA only): logs in first/nvverbose/"
  grep -h -e "Compiling entry" -e "Used [0-9]* registers" -e "bytes stack frame" "$FIRST"/nvverbose/*.log 2>/dev/null | head -n 80
}
first_eval() {
  SPX_KERNEL_PROFILE=1 SPX_TAPE_PROFILE=2 "$B/bench_unet" --width "$UW" --size "$USIZE" --reps 2 --eval-batch 1 --no-train
}
first_train() {
  SPX_KERNEL_PROFILE=1 SPX_TAPE_PROFILE=2 "$B/bench_unet" --width "$UW" --size "$USIZE" --reps 2 --batch 1 --no-eval
}
first_conv() { SPX_KERNEL_PROFILE=1 "$B/bench_conv2d" 2 $CDIV; }
first_clblast() {
  [ -x "$B/bench_clblast" ] || { echo "no bench_clblast in the kit (CLBlast was not found where it was packed)"; return 3; }
  "$B/bench_clblast" 2 $CDIV
}
export -f first_devices first_dump first_mma first_nvverbose first_eval first_train first_conv first_clblast

run_first() {
  local t0 s
  t0=$(date +%s)
  CDIV=""
  [ "$QUICK" = 1 ] && CDIV="--div 8"
  export CDIV
  say "== first step: what explains the gap (budget ${FIRST_BUDGET}s)"
  GROUP_END=$((t0 + FIRST_BUDGET * ${SPX_RUN_LIMIT_SCALE:-1}))
  step first_devices 30 first_devices
  cat "$LOG/first_devices.log" >>"$SUM"
  step first_dump 60 first_dump
  tail -n 3 "$LOG/first_dump.log" >>"$SUM"
  ls "$FIRST/programs"/*.log >/dev/null 2>&1 && say "failed program builds: $(cd "$FIRST/programs" && ls *.log | tr '\n' ' ')"
  for s in first_mma:10 first_nvverbose:25 first_eval:30 first_train:40 first_conv:40 first_clblast:60; do
    step "${s%:*}" "${s#*:}" "${s%:*}"
  done
  GROUP_END=""
  for s in first_devices first_dump first_mma first_nvverbose first_eval first_train first_conv first_clblast; do
    cp "$LOG/$s.log" "$FIRST/" 2>/dev/null
  done
  tar -czf "$OUT/first.tgz" -C "$W" first
  first_summary >>"$SUM" 2>&1
  say "first step: $(($(date +%s) - t0))s; $(ls "$FIRST/programs"/*.ptx 2>/dev/null | wc -l) PTX files in first.tgz (read them here: scripts/device/analyse_ptx.sh OUT_DIR)"
}

# NVIDIA's own figures for the hot kernels (scripts/device/gpu_kernels.txt) from the -cl-nv-verbose logs
nv_verbose_table() {
  cat "$FIRST"/nvverbose/*.log 2>/dev/null | awk -v hot="$(awk '$1 == "kernel" { printf "%s ", $2 }' "$ROOT/scripts/device/gpu_kernels.txt")" '
    function num(re, t) { if (!match($0, re)) return "?"; t = substr($0, RSTART, RLENGTH); sub(/ .*/, "", t); return t }
    BEGIN { n = split(hot, h, " "); for (i = 1; i <= n; i++) want[h[i]] = 1 }
    /Compiling entry function/ { k = $0; sub(/.*function \047/, "", k); sub(/\047.*/, "", k) }
    /Function properties for/ { f = $NF }
    /bytes stack frame/ { st[f] = num("[0-9]+ bytes stack frame"); sp[f] = num("[0-9]+ bytes spill stores") "/" num("[0-9]+ bytes spill loads") }
    /Used [0-9]+ registers/ && k in want {
      m = num("[0-9]+ bytes smem")
      printf "  %-30s %4s registers, spills %s, stack %s, local %s B\n", k, num("[0-9]+ registers"), sp[k] == "" ? "?" : sp[k],
        st[k] == "" ? "?" : st[k], m == "?" ? 0 : m
      k = "" }'
}

# the first "kernel profile" table of a log: its header and the top n rows
kprof_top() {
  [ -f "$1" ] || { echo "  (no $(basename "$1"))"; return 0; }
  awk -v n="$2" '/kernel profile \(device time per command/ { on = 1; print; next }
    on && /^  / && c < n { print; c++ } on && !/^  / { on = 0 }' "$1"
}

# the n slowest forward layers of a tape profile (per-layer lines, SPX_TAPE_PROFILE=2)
layers_top() {
  [ -f "$1" ] || { echo "  (no $(basename "$1"))"; return 0; }
  grep -m 1 'tape profile per forward op' "$1"
  awk '/tape profile per forward op/ { on = 1; next } /tape profile per backward op/ { on = 0 }
    on && /^  #/ { for (i = 2; i <= NF; i++) if ($i == "ms") { printf "%s\t%s\n", $(i - 1), $0; break } }' "$1" |
    sort -t"$(printf '\t')" -k1,1 -rn | head -n "$2" | cut -f2-
}

# ours (forward, backward data, backward weights) and CLBlast's two routes per layer shape, from
# the CONV lines: ms and the share of the roof that bounds the shape
conv_table() {
  cat "$LOG/first_conv.log" "$LOG/first_clblast.log" 2>/dev/null | awk '
    /^CONV / { delete f; for (i = 2; i <= NF; i++) { split($i, kv, "="); f[kv[1]] = kv[2] }
      k = f["cin"] "->" f["cout"] " " f["k"] "x" f["k"] " " f["h"] "x" f["w"]
      if (!(k in seen)) { seen[k] = 1; order[++n] = k }
      c = f["impl"] == "smplpix" ? f["mode"] : f["impl"]
      v[k, c] = sprintf("%.2f (%.0f%%%s)", f["ms"], f["pct_roof"], f["bound"] == "memory" ? "bw" : "") }
    END { if (!n) { print "  (no CONV lines: see first_conv.log, first_clblast.log)"; exit }
      printf "  %-22s %-15s %-15s %-15s %-17s %-17s\n", "shape", "ours fwd ms", "bwd-data ms", "bwd-weights ms", "CLBlast convgemm", "im2col+GEMM"
      for (i = 1; i <= n; i++) { k = order[i]
        printf "  %-22s %-15s %-15s %-15s %-17s %-17s\n", k, v[k, "fwd"], v[k, "bwd_data"], v[k, "bwd_weights"],
          v[k, "clblast_convgemm"], v[k, "clblast_im2col_gemm"] } }'
}

first_summary() {
  echo "-- the roofline (smplpix devices --peak):"
  grep -h '^peak ' "$LOG/first_devices.log" 2>/dev/null || echo "  (not measured: first_devices.log)"
  echo "-- inline PTX tensor cores: $(grep -h '^mma.sync' "$LOG/first_mma.log" 2>/dev/null || echo 'no answer (first_mma.log)')"
  echo "-- NVIDIA's own registers / spills of the hot kernels (-cl-nv-verbose):"
  nv_verbose_table | grep . || echo "  (none: not NVIDIA, or first_nvverbose did not run)"
  echo "-- kernels of a width-$UW eval forward, batch 1 (device time, SPX_KERNEL_PROFILE=1):"
  kprof_top "$LOG/first_eval.log" 12
  grep -h '^roofline eval' "$LOG/first_eval.log" 2>/dev/null
  echo "-- kernels of a width-$UW training step, batch 1:"
  kprof_top "$LOG/first_train.log" 12
  grep -h '^roofline train' "$LOG/first_train.log" 2>/dev/null
  echo "-- the slowest layers of the eval forward (SPX_TAPE_PROFILE=2; work, share of the roofline):"
  layers_top "$LOG/first_eval.log" 8
  echo "-- the UNet-64 layer shapes alone: ms (share of the roof that bounds them: FMA peak, or bandwidth 'bw')"
  conv_table
}
