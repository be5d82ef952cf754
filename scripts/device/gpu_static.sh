#!/bin/sh
# make gpu-static: every kernel program as the GPU class builds it, compiled for NVIDIA here, no GPU
# needed (docs/gpu.md, "The static GPU check"):
#   1. NVIDIA's ptxas and nvdisasm, pinned (scripts/device/nvidia_tools.sh, into the cache as
#      `make weights` does); a failed download skips the whole check with one line (exit 0), a
#      mismatched hash is an error
#   2. the sources and options of the GPU class (scripts/device/gpu_common.sh, as clang_check.sh)
#   3. each program through clang-15 + libclc-15 to PTX (gpu_common.sh spx_nvptx_libclc), in parallel
#   4. scripts/device/ptx_report.py --check with scripts/device/gpu_kernels.txt: ptxas -arch=sm_90
#      -v and nvdisasm per kernel; the table of the hot kernels (registers against their budget,
#      spills, stack, local memory, occupancy at their work-group size, the inner loop's FFMA share)
# Fails (exit 1, naming kernel and rule) on a spill or stack frame in a strict kernel (convolution,
# GEMM, Winograd) beyond its waiver, more than 48 KiB of local memory in any kernel, a hot kernel
# over its register budget, a rules row naming no kernel. Output and the table as Markdown (for
# docs/gpu.md): BUILD/gpu-static/ (PTX, cubins, listings, ptxas logs, table.md).
# usage: scripts/device/gpu_static.sh [BUILD_DIR]   env: CLANG_NVPTX (clang-15), LIBCLC_NVPTX
#        (/usr/lib/clc/nvptx64--nvidiacl.bc), JOBS (nproc), SPX_CACHE_DIR, PYTHON
set -eu
cd "$(dirname "$0")/../.."
BUILD=${1:-build}
CLANG=${CLANG_NVPTX:-clang-15}
LIBCLC=${LIBCLC_NVPTX:-/usr/lib/clc/nvptx64--nvidiacl.bc}
JOBS=${JOBS:-$(nproc 2>/dev/null || echo 2)}
PY=${PYTHON:-python3}
t0=$(date +%s)
[ -x "$BUILD/smplpix" ] || { echo "gpu-static: $BUILD/smplpix not built" >&2; exit 1; }
command -v "$CLANG" >/dev/null || { echo "gpu-static: $CLANG not found (scripts/deps.sh installs clang-15)" >&2; exit 1; }
[ -f "$LIBCLC" ] || { echo "gpu-static: $LIBCLC not found (scripts/deps.sh installs libclc-15)" >&2; exit 1; }

set +e
tools=$(sh scripts/device/nvidia_tools.sh)
rc=$?
set -e
case $rc in
0) ;;
3) echo "gpu-static: skipped: NVIDIA's ptxas / nvdisasm are not available (the line above says why)" >&2; exit 0 ;;
*) exit 1 ;;
esac

. scripts/device/gpu_common.sh
out=$BUILD/gpu-static
rm -rf "$out"
mkdir -p "$out/ptx"
spx_dump_gpu_programs "$BUILD" "$out/src" "$out/warmup.log" ||
  { echo "gpu-static: smplpix devices --warmup failed:" >&2; cat "$out/warmup.log" >&2; exit 1; }

# each program NAME.cl -> ptx/NAME.ptx (its clang log beside it), JOBS at a time; the failed ones named
export CLANG_NVPTX=$CLANG LIBCLC_NVPTX=$LIBCLC
ls "$out/src" | sed -n 's/\.cl$//p' | xargs -P "$JOBS" -I{} \
  sh -c '. scripts/device/gpu_common.sh && spx_nvptx_libclc "$1" "$2" "$3" || echo "$2"' _ "$out/src" {} "$out/ptx" \
  >"$out/clang-failed.txt"
if [ -s "$out/clang-failed.txt" ]; then
  for p in $(cat "$out/clang-failed.txt"); do
    echo "gpu-static: FAIL $p.cl: clang: $(grep -m1 error "$out/ptx/$p.clang.log" || head -n1 "$out/ptx/$p.clang.log")" >&2
  done
  exit 1
fi

set +e
"$PY" scripts/device/ptx_report.py --ptxas "$tools/ptxas" --nvdisasm "$tools/nvdisasm" --arch sm_90 \
  --rules scripts/device/gpu_kernels.txt --work "$out/work" --jobs "$JOBS" --check --markdown-out "$out/table.md" \
  "$out/ptx" >"$out/report.txt" 2>&1
rc=$?
set -e
cat "$out/report.txt"
n=$(ls "$out/ptx"/*.ptx | wc -l)
echo "gpu-static: $n programs, $($CLANG --version | head -n 1), $("$tools/ptxas" --version | tail -n 1); $(($(date +%s) - t0)) s; table: $out/table.md"
[ "$rc" -eq 0 ] || { echo "gpu-static: FAILED (the FAIL lines above)" >&2; exit 1; }
