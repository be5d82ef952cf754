#!/bin/bash
# The GPU machine kit's run (docs/gpu.md): from the repository root, with the kit of
# scripts/device/pack.sh (SPX_KIT, default .device-kit/) carried along. Writes to $OUT (default
# out/device/) at most 8 files: summary.txt (steps, times, results tables), first.tgz (the first
# step's PTX, NVIDIA's -cl-nv-verbose logs and every log of that step: scripts/device/analyse_ptx.sh
# reads it here), logs.tgz (every log, the programs' sources, options and failed build logs, the
# tuning file, the benchmarks' CSV/JSON), bench.txt (the benchmarks' ROW lines) and ctest.txt.
#   SPX_DEVICE=gpu (default): find the NVIDIA OpenCL driver under the driver's folders, register it
#                 in a private ICD folder (OCL_ICD_VENDORS), and run everything on it
#   SPX_DEVICE=cpu: the same steps on PoCL (the local smoke test; scripts/device/test_clean_root.sh)
# Steps, each bounded by its own time limit and logged whatever the previous one did:
#   env, icd, then the first step (scripts/device/run_first.sh, FIRST_BUDGET seconds, default 90:
#   devices and the measured roofline, every program built with its PTX kept, the inline-PTX
#   mma.sync probe, -cl-nv-verbose builds of the convolution programs, the per-kernel and per-layer
#   profile of a width-64 eval and training step at batch 1, the UNet-64 layer shapes alone, ours
#   and CLBlast's; first.tgz and its summary written at once), ctest (the suite on the device),
#   tune (smplpix tune --quick, its choice reported, not applied), latency (bench_latency), unet
#   (bench_unet and the PyTorch peer on the same GPU: eval and train, width 64, batch 1 and 10,
#   float32 and TF32), profile (bench_unet's per-layer and per-kernel device times at eval batch 10
#   and width 16), conv2 (bench_conv2d with CONV_LDS=2), project (bench_project: up to 10^6
#   points), raster (bench_raster), then the summary.
# The whole run stays under SPX_RUN_BUDGET seconds (default 450): a step that would start with
# less than its limit left is skipped and says so.
# env: SPX_KIT, OUT, SPX_RUN_BUDGET, FIRST_BUDGET, SPX_CTEST_REGEX (-R for ctest; default all),
#      SPX_CTEST_JOBS, SPX_CTEST_TIMEOUT (per test, default 150), SPX_RUN_SWEEP (settings to time,
#      see sweep_rows), PYTHON (default: python3 on PATH), SPX_RUN_SKIP (space-separated step
#      names to skip), SPX_RUN_QUICK=1 (small benchmark sizes and no tuning, for the CPU smoke
#      test), SPX_RUN_LIMIT_SCALE (multiplies every step's limit and FIRST_BUDGET; default 1)
set -u
ROOT=$(pwd)
[ -f "$ROOT/scripts/device/run.sh" ] || { echo "run.sh: run it from the repository root" >&2; exit 2; }
KIT=${SPX_KIT:-$ROOT/.device-kit}
case $KIT in /*) ;; *) KIT="$ROOT/$KIT" ;; esac
OUT=${OUT:-$ROOT/out/device}
case $OUT in /*) ;; *) OUT="$ROOT/$OUT" ;; esac
DEV=${SPX_DEVICE:-gpu}
BUDGET=${SPX_RUN_BUDGET:-450}
FIRST_BUDGET=${FIRST_BUDGET:-90}
GROUP_END="" # set by run_first: the end of the first step's own budget (epoch seconds)
PY=${PYTHON:-python3}
START=$(date +%s)
W=$(mktemp -d /tmp/spx-device.XXXXXX)
LOG=$W/logs
mkdir -p "$OUT" "$LOG" "$W/vendors" "$W/cache"
SUM=$OUT/summary.txt
: >"$SUM"
say() { echo "$*" | tee -a "$SUM"; }

# step NAME LIMIT CMD...: run CMD (stdout+stderr to logs/NAME.log) under `timeout LIMIT`
step() {
  local name=$1 limit=$2 t0 rc left
  shift 2
  case " ${SPX_RUN_SKIP:-} " in *" $name "*) say "step $name: skipped (SPX_RUN_SKIP)"; return 0 ;; esac
  left=$((BUDGET - ($(date +%s) - START)))
  if [ "$left" -lt 10 ]; then
    say "step $name: skipped (${left}s of the ${BUDGET}s budget left)"
    return 0
  fi
  limit=$((limit * ${SPX_RUN_LIMIT_SCALE:-1}))
  [ "$limit" -le "$left" ] || limit=$left
  if [ -n "$GROUP_END" ]; then
    left=$((GROUP_END - $(date +%s)))
    if [ "$left" -lt 5 ]; then
      say "step $name: skipped (the first step's ${FIRST_BUDGET}s are spent)"
      return 0
    fi
    [ "$limit" -le "$left" ] || limit=$left
  fi
  t0=$(date +%s)
  # through bash, so that CMD may be one of the exported functions below
  timeout -k 5 "$limit" bash -c '"$@"' _ "$@" >"$LOG/$name.log" 2>&1
  rc=$?
  if [ $rc = 124 ] || [ $rc = 137 ]; then
    say "step $name: TIMEOUT after ${limit}s (log: $name.log)"
  else
    say "step $name: rc=$rc in $(($(date +%s) - t0))s (log: $name.log)"
  fi
  return 0
}

[ -x "$KIT/build/smplpix" ] || { say "run.sh: no kit at $KIT (scripts/device/pack.sh)"; exit 1; }
# the executables read tests/data and data/ under the source root they were built in
src=$(sed -n 's/^source_root //p' "$KIT/manifest")
if [ -n "$src" ] && [ "$src" != "$ROOT" ] && [ ! -e "$src" ]; then
  mkdir -p "$(dirname "$src")" && ln -s "$ROOT" "$src" || say "run.sh: cannot link $src to $ROOT: tests will not find their data"
fi
kit_src=$(sed -n 's/^kit //p' "$KIT/manifest")
if [ -n "$kit_src" ] && [ "$kit_src" != "$KIT" ] && [ ! -e "$kit_src" ]; then
  mkdir -p "$(dirname "$kit_src")" && ln -s "$KIT" "$kit_src"
fi
export LD_LIBRARY_PATH="$KIT/lib:$KIT/build${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# the kit's C++ runtime needs the glibc it was built against (manifest: "needs"); on an older
# glibc, take the machine's own libstdc++ / libgcc_s instead (the CUDA image has them)
if ! "$KIT/build/smplpix" --version >/dev/null 2>"$W/exec.err" && grep -q 'GLIBC_' "$W/exec.err"; then
  mkdir -p "$W/kitlib"
  for f in "$KIT"/lib/*; do
    case $(basename "$f") in libstdc++.so.* | libgcc_s.so.*) ;; *) ln -s "$f" "$W/kitlib/" ;; esac
  done
  export LD_LIBRARY_PATH="$W/kitlib:$KIT/build${LD_LIBRARY_PATH#"$KIT/lib:$KIT/build"}"
  say "run.sh: $(head -n 1 "$W/exec.err"); using the machine's libstdc++ and libgcc_s"
fi
export SPX_CACHE_DIR=$W/cache SPX_DEVICE=$DEV
SPX=$KIT/build/smplpix
B=$KIT/build/benchmarks
export KIT LOG SPX B PY ROOT DEV W

# --- env
env_info() {
  echo "date: $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
  echo "host: $(uname -srm), $(nproc) cores"
  sed 's/^/kit: /' "$KIT/manifest"
  echo "glibc here: $(ldd --version 2>&1 | head -n 1)"
  command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm,clocks.sm --format=csv
  echo "python: $(command -v "$PY") $("$PY" -c 'import sys; print(sys.version.split()[0])' 2>&1)"
  echo "ldd smplpix:"
  ldd "$SPX"
}
export -f env_info
step env 20 env_info

# --- icd: the vendor library, registered in a private folder for the kit's ocl-icd loader
find_icd() {
  local pats dirs f
  if [ "$DEV" = cpu ]; then
    pats="libpocl.so.2 libpocl.so"
    dirs="/usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /usr/local/lib"
  else
    pats="libnvidia-opencl.so.1 libnvidia-opencl.so"
    dirs="/usr/local/nvidia/lib64 /usr/local/nvidia/lib /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /usr/local/cuda/lib64 /usr/local/cuda/compat"
  fi
  for p in $pats; do
    for d in $dirs; do
      [ -e "$d/$p" ] && { echo "$d/$p"; return 0; }
    done
  done
  # anywhere under the driver's mount, then the library folders
  for d in /usr/local/nvidia /usr/lib /usr/lib64 /opt; do
    [ -d "$d" ] || continue
    f=$(find "$d" -maxdepth 5 -name "${pats%% *}*" 2>/dev/null | head -n 1)
    [ -n "$f" ] && { echo "$f"; return 0; }
  done
  return 1
}
icd_lib=$(find_icd || true)
if [ -n "$icd_lib" ]; then
  echo "$icd_lib" >"$W/vendors/spx.icd"
  export OCL_ICD_VENDORS=$W/vendors
  # the driver's other libraries (libcuda.so.1, ...) beside it
  export LD_LIBRARY_PATH="$LD_LIBRARY_PATH:$(dirname "$icd_lib")"
  say "icd: $icd_lib"
else
  say "icd: no OpenCL library for SPX_DEVICE=$DEV found; existing ICD files:"
  ls -l /etc/OpenCL/vendors 2>&1 | tee -a "$SUM"
  find /usr/local/nvidia -maxdepth 3 2>/dev/null | head -n 60 >"$LOG/nvidia-tree.log"
fi
icd_check() {
  echo "OCL_ICD_VENDORS=${OCL_ICD_VENDORS:-}"
  cat "$W/vendors/spx.icd" 2>/dev/null
  [ -n "$icd_lib" ] && ldd "$icd_lib"
  ls -l /etc/OpenCL/vendors 2>&1
  ls /usr/local/nvidia /usr/local/nvidia/lib64 2>&1 | head -n 80
}
export icd_lib
export -f icd_check
step icd 20 icd_check

# --- the first step (scripts/device/run_first.sh): devices, the roofline, every program (its PTX
# kept), the probes, the width-64 profiles and the layer shapes; first.tgz and its summary at once
QUICK=${SPX_RUN_QUICK:-0}
if [ "$QUICK" = 1 ]; then
  UW=16 USIZE=64x96 UREPS=1 UBATCH="1 2" LFRAMES=3 LWIDTHS=16 PRUNS=3 RFRAMES=3
  export SPX_BENCH_NO_GL=1
else
  UW=64 USIZE=308x410 UREPS=5 UBATCH="1 10" LFRAMES=21 LWIDTHS=64,32,16 PRUNS=20 RFRAMES=21
fi
export UW USIZE UREPS UBATCH QUICK
. "$ROOT/scripts/device/run_first.sh"
run_first

# --- the test suite on the device (its own program cache, warmed by the step above per test)
run_ctest() {
  local args="-j ${SPX_CTEST_JOBS:-8} --timeout ${SPX_CTEST_TIMEOUT:-150} --output-on-failure"
  args="$args -E ^(install_consumer|python_bindings|python_pip_install|table1_quick|test_cli_train_mpi)$"
  cd "$KIT/build" && ctest $args ${SPX_CTEST_REGEX:+-R "$SPX_CTEST_REGEX"}
}
export -f run_ctest
step ctest 200 run_ctest
grep -E '^[0-9]+% tests passed|tests failed|\(Failed\)|\(Timeout\)|\*\*\*' "$LOG/ctest.log" | head -n 40 >>"$SUM"
cp "$LOG/ctest.log" "$OUT/ctest.txt" 2>/dev/null

# --- tuning, in a copy of the program cache: its tuning file is reported (summary, logs), not
# applied, so the benchmarks below time the defaults (a batch-1 choice applied to them had made
# the batch-10 eval four times slower on the H200); SPX_RUN_SWEEP times other settings
if [ "$QUICK" = 1 ]; then
  say "step tune: skipped (SPX_RUN_QUICK=1)"
else
  cp -r "$W/cache" "$W/tune-cache" 2>/dev/null
  step tune 90 env SPX_CACHE_DIR="$W/tune-cache" "$SPX" tune --quick --width 64 --device "$DEV"
fi
tail -n 5 "$LOG/tune.log" >>"$SUM" 2>/dev/null

# --- benchmarks (bench_latency and bench_unet write out/bench/ under the working directory)
mkdir -p "$W/run/out" && cd "$W/run" || exit 1
step latency 60 "$B/bench_latency" --frames "$LFRAMES" --warmup 3 --widths "$LWIDTHS"
have_torch=0
if "$PY" -c 'import torch, sys; sys.exit(0 if torch.cuda.is_available() else 3)' >"$LOG/torch.log" 2>&1; then
  have_torch=1
elif [ "$DEV" = gpu ]; then
  say "torch peer skipped: $PY cannot import torch or sees no CUDA device ($(tail -n 1 "$LOG/torch.log"))"
fi
unet_rows() {
  for b in $UBATCH; do
    "$B/bench_unet" --width "$UW" --size "$USIZE" --reps "$UREPS" --eval-batch "$b" --batch "$b"
  done
}
export -f unet_rows
step unet 90 unet_rows
torch_rows() {
  for tf in off on; do
    for b in $UBATCH; do
      "$PY" "$ROOT/benchmarks/peer_unet_torch.py" --device cuda --tf32 "$tf" --width "$UW" --size "$USIZE" \
        --reps "$UREPS" --eval-batch "$b" --batch "$b"
    done
  done
}
export -f torch_rows
if [ $have_torch = 1 ]; then step unet_torch 60 torch_rows; fi
# the tape's per-layer device times (SPX_TAPE_PROFILE=2: each op finished before the next, so
# their sum against the unprofiled pass shows the launch overhead) and each OpenCL command's own
# device time per kernel name (SPX_KERNEL_PROFILE=1), beyond the first step's batch 1: width 64
# eval at batch 10, width 16 eval at batch 1
profile_rows() {
  export SPX_TAPE_PROFILE=2 SPX_KERNEL_PROFILE=1
  "$B/bench_unet" --width "$UW" --size "$USIZE" --reps 1 --eval-batch "${UBATCH##* }" --no-train
  "$B/bench_unet" --width 16 --size "$USIZE" --reps 2 --eval-batch 1 --no-train
}
export -f profile_rows
step profile 45 profile_rows
# the layer shapes alone again with the register-row local-memory 3x3 kernel (CONV_LDS=2; the first
# step timed the defaults' CONV_LDS=1)
conv2_rows() { SPX_KERNEL_PROFILE=1 SPX_TUNE_CONV_LDS=2 "$B/bench_conv2d" 3; }
export -f conv2_rows
if [ "$QUICK" = 1 ]; then say "step conv2: skipped (SPX_RUN_QUICK=1)"; else step conv2 40 conv2_rows; fi
# SPX_RUN_SWEEP: tunable settings to time against the defaults, ';'-separated, each a
# space-separated list of SPX_TUNE_NAME=value (e.g. "SPX_TUNE_CONV_LDS=0;SPX_TUNE_CONV_LWS=128"):
# bench_unet eval and training step, width 64, batch 1, per setting (empty: the step is skipped)
sweep_rows() {
  local cfg
  echo "$SPX_RUN_SWEEP" | tr ';' '\n' | while read -r cfg; do
    [ -n "$cfg" ] || continue
    [ "$cfg" = defaults ] && set -- || set -- $cfg
    env "$@" "$B/bench_unet" --width "$UW" --size "$USIZE" --reps 3 --eval-batch 1 --batch 1 2>&1 |
      sed -n "s|^ROW |SWEEP cfg=${cfg// /,} |p"
  done
}
export -f sweep_rows
if [ -n "${SPX_RUN_SWEEP:-}" ]; then
  export SPX_RUN_SWEEP="defaults;$SPX_RUN_SWEEP"
  step sweep "${SPX_SWEEP_LIMIT:-150}" sweep_rows
  grep '^SWEEP' "$LOG/sweep.log" | awk '{ c = $2; for (i = 3; i <= NF; i++) { split($i, kv, "="); f[kv[1]] = kv[2] }
    print "sweep", c, f["mode"], f["ms"] " ms" }' >>"$SUM"
fi
step project 45 "$B/bench_project" "$PRUNS"
step raster 30 "$B/bench_raster" "$RFRAMES"
cd "$ROOT" || exit 1
cp -r "$W/run/out/bench" "$LOG/bench" 2>/dev/null
grep -h '^ROW' "$LOG"/unet.log "$LOG"/unet_torch.log 2>/dev/null >"$OUT/bench.txt"

# --- summary: the UNet rows side by side, GFLOP/s against the measured float32 FMA peak (the first
# step's `smplpix devices --peak`), the nominal one beside it
summary() {
  local cu mhz nominal peak
  cu=$(sed -n 's/.*| \([0-9]*\) CU |.*/\1/p' "$LOG/first_devices.log" | head -n 1)
  mhz=$(nvidia-smi --query-gpu=clocks.max.sm --format=csv,noheader,nounits 2>/dev/null | head -n 1 | tr -d ' ')
  nominal=0
  # NVIDIA Hopper / Ampere: 128 float32 lanes per multiprocessor, 2 flops per fma
  [ -n "$cu" ] && [ -n "$mhz" ] && nominal=$((cu * 128 * 2 * mhz / 1000))
  peak=$(sed -n 's/^peak .*: \([0-9.]*\) GFLOP\/s fp32 FMA.*/\1/p' "$LOG/first_devices.log" | head -n 1)
  peak=${peak:-$nominal}
  echo "float32 peak: ${peak} GFLOP/s measured (smplpix devices --peak); nominal ${nominal} GFLOP/s (${cu:-?} CU x 128 lanes x 2 x ${mhz:-?} MHz; 0 = unknown)"
  awk -v peak="$peak" '
    /^ROW/ { delete f; for (i = 2; i <= NF; i++) { split($i, kv, "="); f[kv[1]] = kv[2] }
             k = f["mode"] " b" f["batch"] " w" f["width"]; keys[k] = 1
             ms[k, f["impl"]] = f["ms"]; gf[k, f["impl"]] = f["gflops"]; impls[f["impl"]] = 1 }
    END { printf "%-18s %10s %10s %10s %8s %8s %9s %7s\n", "row", "ours ms", "cuda ms", "tf32 ms", "ours/cuda", "ours/tf32", "ours GF/s", "%peak"
          for (k in keys) {
            o = ms[k, "smplpix"]; c = ms[k, "torch_cuda"]; t = ms[k, "torch_cuda_tf32"]
            printf "%-18s %10s %10s %10s %8s %8s %9s %7s\n", k, o == "" ? "-" : o, c == "" ? "-" : c, t == "" ? "-" : t,
              (o != "" && c != "") ? sprintf("%.2f", o / c) : "-", (o != "" && t != "") ? sprintf("%.2f", o / t) : "-",
              gf[k, "smplpix"] == "" ? "-" : gf[k, "smplpix"], (peak > 0 && gf[k, "smplpix"] != "") ? sprintf("%.1f", 100 * gf[k, "smplpix"] / peak) : "-" } }' "$OUT/bench.txt"
  echo "latency (bench_latency):"
  grep -E '^ *(project|raster|llvmpipe|project\+unet)' "$LOG/latency.log" | head -n 20
  echo "projection (bench_project):"
  tail -n 8 "$LOG/project.log"
  echo "raster (bench_raster):"
  tail -n 6 "$LOG/raster.log"
}
summary >>"$SUM" 2>&1
say "total: $(($(date +%s) - START))s of ${BUDGET}s"
cp "$W/cache"/tuning-*.txt "$W/tune-cache"/tuning-*.txt "$LOG/" 2>/dev/null
tar -czf "$OUT/logs.tgz" -C "$W" logs
rm -rf "$W"
cat "$SUM"
