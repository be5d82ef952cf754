#!/bin/sh
# The offline PTX tools of the GPU kit and of make gpu-static:
#   1. tests/ptx_report_test.py: the sm_90 occupancy arithmetic, the ptxas / nvdisasm parsers, the
#      inner-loop finder and every rule of --check (each must fire)
#   2. the kit's path end to end on PTX made here (CPU PoCL returns no PTX): peak.cl and
#      conv2d_lds.cl as the GPU class builds them (SPX_CL_DUMP_DIR), through clang-15 + libclc-15
#      (scripts/device/gpu_common.sh) to PTX, packed like the kit's $OUT/first.tgz with a
#      -cl-nv-verbose-style log (ptxas -v's own output, the format NVIDIA's driver writes) and the
#      peak program's PTX marked ISA 9.9 (newer than any pinned ptxas), then
#      scripts/device/analyse_ptx.sh on it: the FMA peak kernel's inner loop must be >= 95% FFMA
#      with no stack, the 3x3 kernel's row must carry the driver's register count, the PTX version
#      must have been lowered and noted.
# Part 2 needs clang-15, libclc-15 and NVIDIA's ptxas + nvdisasm already installed (make gpu-static
# puts them in ~/.cache/smplpix/nvidia-tools; or set PTXAS and NVDISASM): this test never
# downloads them; without them it says so and part 1 decides. Exit 77 without python3.
# usage: tests/gpu_static_tools.sh SOURCE_DIR BUILD_DIR TMP
set -eu
SRC=$1 BUILD=$2 T=$3
command -v python3 >/dev/null || { echo "gpu_static_tools: no python3: skipped"; exit 77; }
python3 "$SRC/tests/ptx_report_test.py" || { echo "gpu_static_tools: FAIL: ptx_report's unit tests" >&2; exit 1; }

tools=${HOME:-/nonexistent}/.cache/smplpix/nvidia-tools
PTXAS=${PTXAS:-$tools/ptxas} NVDISASM=${NVDISASM:-$tools/nvdisasm}
for need in "$PTXAS" "$NVDISASM" "$(command -v clang-15 || echo clang-15)" /usr/lib/clc/nvptx64--nvidiacl.bc; do
  [ -e "$need" ] || { echo "gpu_static_tools: $need absent (make gpu-static installs NVIDIA's tools): end-to-end part skipped"; exit 0; }
done
export PTXAS NVDISASM
rm -rf "$T" && mkdir -p "$T/first/programs" "$T/first/nvverbose" "$T/dump"
cd "$SRC"
. scripts/device/gpu_common.sh
spx_dump_gpu_programs "$BUILD" "$T/dump" "$T/warmup.log" || { cat "$T/warmup.log" >&2; exit 1; }
for p in peak conv2d_lds; do
  spx_nvptx_libclc "$T/dump" "$p" "$T/first/programs" || { cat "$T/first/programs/$p.clang.log" >&2; exit 1; }
done
"$PTXAS" -arch=sm_90 -v -o "$T/lds.cubin" "$T/first/programs/conv2d_lds.ptx" >"$T/first/nvverbose/conv2d_lds.log" 2>&1
# a driver newer than the pinned ptxas writes a newer PTX ISA version: assembled with it lowered
sed 's/^\.version .*/.version 9.9/' "$T/first/programs/peak.ptx" >"$T/peak.ptx" && mv "$T/peak.ptx" "$T/first/programs/peak.ptx"
tar -czf "$T/first.tgz" -C "$T" first
sh scripts/device/analyse_ptx.sh "$T/first.tgz" >"$T/report.txt" 2>&1 || { cat "$T/report.txt" >&2; exit 1; }
cat "$T/report.txt"
fail=0
peak=$(grep '^spx_peak_fma ' "$T/report.txt" || true)
share=$(echo "$peak" | sed -n 's/.*FFMA \([0-9]*\)%.*/\1/p')
[ -n "$share" ] && [ "$share" -ge 95 ] || { echo "gpu_static_tools: FAIL: spx_peak_fma's inner loop is not >= 95% FFMA: $peak" >&2; fail=1; }
echo "$peak" | grep -q ' 0/0 .* 0 ' || { echo "gpu_static_tools: FAIL: spx_peak_fma spills or has a stack frame" >&2; fail=1; }
grep -q '^spx_conv2d_fwd_k3s1_lds .*(driver [0-9]*)' "$T/report.txt" ||
  { echo "gpu_static_tools: FAIL: the driver log's registers are not beside spx_conv2d_fwd_k3s1_lds" >&2; fail=1; }
grep -q '^note: peak: .version 9.9 lowered to ' "$T/report.txt" ||
  { echo "gpu_static_tools: FAIL: a PTX version newer than ptxas's was not lowered (or not noted)" >&2; fail=1; }
# a partial set of programs is not a complete one: --check calls the other rules' kernels missing
if sh scripts/device/analyse_ptx.sh --check "$T/first.tgz" >"$T/check.txt" 2>&1; then
  echo "gpu_static_tools: FAIL: --check on two programs passed; it must call the rules' other kernels missing" >&2
  fail=1
fi
[ $fail = 0 ] && echo "gpu_static_tools: PASS"
exit $fail
