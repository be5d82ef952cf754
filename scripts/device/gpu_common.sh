# Sourced (POSIX sh) by the offline GPU checks, scripts/device/clang_check.sh (make clang-check)
# and scripts/device/gpu_static.sh (make gpu-static): what they share.
#
# spx_dump_gpu_programs BUILD DIR LOG: every kernel program's full source (DIR/NAME.cl) and build
#   options (DIR/NAME.cl.opts) exactly as the library builds them for a GPU-class device
#   (SPX_TUNE_CLASS=gpu; `smplpix devices --warmup` with SPX_CL_DUMP_DIR on the local device,
#   SPX_CLANG_CHECK_DEVICE, default cpu; program cache SPX_CACHE_DIR, default BUILD/cl-cache);
#   the warmup's output to LOG. Returns its exit status.
# SPX_CL_C12: clang's flags for OpenCL C 1.2 as NVIDIA's compiler takes it: the default header,
#   no cl_khr_fp64 and no cl_khr_fp16 (the source comes with -x cl, its options from NAME.cl.opts).
# SPX_NVPTX: the target of NVIDIA's OpenCL driver (64-bit PTX, OpenCL's nvcl environment).
# spx_nvptx_libclc SRC NAME OUT: SRC/NAME.cl with its options SRC/NAME.cl.opts to OUT/NAME.ptx
#   through clang-15 (CLANG_NVPTX) with libclc-15's nvptx built-ins linked (LIBCLC_NVPTX), so
#   get_global_id & co. resolve and ptxas sees a whole program; -O2, PTX for sm_80 (LLVM 15's
#   newest; ptxas assembles it for sm_90). clang's messages to OUT/NAME.clang.log; its status.

SPX_CL_C12="-x cl -Xclang -finclude-default-header -Xclang -cl-ext=-cl_khr_fp64,-cl_khr_fp16"
SPX_NVPTX="-target nvptx64-nvidia-nvcl"

spx_dump_gpu_programs() {
  mkdir -p "$2" || return 1
  SPX_TUNE_CLASS=gpu SPX_CACHE_DIR="${SPX_CACHE_DIR:-$1/cl-cache}" SPX_CL_DUMP_DIR="$2" \
    "$1/smplpix" devices --warmup --device "${SPX_CLANG_CHECK_DEVICE:-cpu}" >"$3" 2>&1
}

spx_nvptx_libclc() {
  # shellcheck disable=SC2046 # the options file is split into words on purpose
  ${CLANG_NVPTX:-clang-15} $SPX_NVPTX -march=sm_80 $SPX_CL_C12 $(cat "$1/$2.cl.opts") -O2 -Wno-linker-warnings \
    -Xclang -mlink-builtin-bitcode -Xclang "${LIBCLC_NVPTX:-/usr/lib/clc/nvptx64--nvidiacl.bc}" \
    -S -o "$3/$2.ptx" "$1/$2.cl" >"$3/$2.clang.log" 2>&1
}
