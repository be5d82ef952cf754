#!/bin/sh
# Compile every kernel program offline with clang for NVIDIA (nvptx64-nvidia-nvcl) and AMD
# (amdgcn-amd-amdhsa, gfx900) as OpenCL C 1.2 without cl_khr_fp64 / cl_khr_fp16, with the exact
# source and options the library would build for a GPU-class device (SPX_TUNE_CLASS=gpu, dumped
# through SPX_CL_DUMP_DIR by `smplpix devices --warmup` on the local device: scripts/device/
# gpu_common.sh, shared with gpu_static.sh), at -O2 and, for
# NVIDIA, -cl-opt-disable; programs that divide (SPX_DIV) also with the integer division that
# devices without correctly rounded division take. Fails (exit 1, naming program and target) on:
#   - a compile error or warning (double, half arithmetic, generic address space, 2.0 built-ins)
#   - a helper called but left without a body (e.g. a plain C99 `inline`): an LLVM `declare`
#     of a function that is neither an OpenCL built-in (mangled _Z...) nor an LLVM intrinsic
#   - more than 48 KiB of static local memory in one NVIDIA kernel
# and lists the NVIDIA kernels that keep a private array on the stack (.local depot) at -O2
# (a note, not a failure: SPX_CLANG_STACK_STRICT=1 fails on them too).
# usage: scripts/device/clang_check.sh [BUILD_DIR]  (default build; needs BUILD_DIR/smplpix)
set -eu
cd "$(dirname "$0")/../.."
BUILD=${1:-build}
CLANG=${CLANG:-clang}
command -v "$CLANG" >/dev/null || { echo "clang_check: $CLANG not found" >&2; exit 1; }
[ -x "$BUILD/smplpix" ] || { echo "clang_check: $BUILD/smplpix not built" >&2; exit 1; }
. scripts/device/gpu_common.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
spx_dump_gpu_programs "$BUILD" "$tmp/src" "$tmp/warmup.log" ||
  { echo "clang_check: smplpix devices --warmup failed:" >&2; cat "$tmp/warmup.log" >&2; exit 1; }
n=0
fails=0
stack=""
fail() {
  echo "clang_check: FAIL $1" >&2
  fails=$((fails + 1))
}
# compile PROGRAM VARIANT TARGET LEVEL: LLVM IR (and PTX for NVIDIA -O2) under $tmp/out
compile() {
  prog=$1 variant=$2 target=$3 level=$4
  opts=$(cat "$tmp/src/$prog.opts")
  if [ "$variant" = intdiv ]; then
    opts=$(printf '%s' "$opts" | sed 's/ -cl-fp32-correctly-rounded-divide-sqrt//; s/-DSPX_CR_DIV=1/-DSPX_CR_DIV=0/')
  fi
  case $target in
  nvptx) triple=$SPX_NVPTX ;;
  amdgcn) triple="-target amdgcn-amd-amdhsa -mcpu=gfx900 -nogpulib" ;;
  esac
  base="$tmp/out/$prog.$variant.$target.$level"
  # shellcheck disable=SC2086 # word splitting of the option strings is intended
  if ! $CLANG $triple $SPX_CL_C12 $opts -Werror $level -S -emit-llvm -o "$base.ll" "$tmp/src/$prog" 2>"$base.err"; then
    fail "$prog ($variant, $target, $level): $(grep -m1 -E 'error' "$base.err" || head -n1 "$base.err")"
    return
  fi
  n=$((n + 1))
  undef=$(grep -E '^declare' "$base.ll" | grep -oE '@[A-Za-z_.$0-9]+' | grep -vE '^@(_Z|llvm\.)' | tr '\n' ' ' || true)
  [ -z "$undef" ] || fail "$prog ($variant, $target, $level): called but never defined: $undef"
  if [ "$target" = nvptx ] && [ "$level" = -O2 ]; then
    $CLANG $SPX_NVPTX -S -o "$base.ptx" "$base.ll" 2>"$base.err" || { fail "$prog: PTX: $(head -n1 "$base.err")"; return; }
    # per .entry: static shared bytes and the stack depot
    awk -v prog="$prog" '
      /^\.entry/ { if (k != "") print k, sh, dep; k = $2; sub(/\(.*/, "", k); sh = 0; dep = 0 }
      /\.shared/ && match($0, /\[[0-9]+\]/) { sh += substr($0, RSTART + 1, RLENGTH - 2) }
      /__local_depot[0-9]+\[/ && match($0, /\[[0-9]+\]/) { dep = substr($0, RSTART + 1, RLENGTH - 2) }
      END { if (k != "") print k, sh, dep }' "$base.ptx" >"$base.entries"
    while read -r k sh dep; do
      [ "$sh" -le 49152 ] || fail "$prog: kernel $k uses $sh bytes of static local memory (NVIDIA: 48 KiB)"
      [ "$dep" -eq 0 ] || stack="$stack $prog:$k($dep B)"
    done <"$base.entries"
  fi
}
mkdir -p "$tmp/out"
for f in "$tmp"/src/*.cl; do
  prog=$(basename "$f")
  variants=cr
  grep -q 'SPX_DIV(' "$f" && variants="cr intdiv"
  for v in $variants; do
    compile "$prog" "$v" nvptx -O2
    compile "$prog" "$v" nvptx -cl-opt-disable
    compile "$prog" "$v" amdgcn -O2
  done
done
[ -z "$stack" ] || echo "clang_check: NVIDIA kernels with a stack frame at -O2:$stack"
if [ -n "$stack" ] && [ "${SPX_CLANG_STACK_STRICT:-0}" = 1 ]; then fail "stack frames (SPX_CLANG_STACK_STRICT=1)"; fi
echo "clang_check: $n compiles of $(ls "$tmp"/src/*.cl | wc -l) programs, $fails failures ($($CLANG --version | head -n1))"
[ "$fails" -eq 0 ]
