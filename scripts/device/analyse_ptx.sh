#!/bin/sh
# The PTX that NVIDIA's OpenCL driver compiled on the GPU machine, read here, offline (docs/gpu.md,
# "Reading the PTX"): per hot kernel of scripts/device/gpu_kernels.txt its registers (against the
# budget), spills, stack frame, local memory, occupancy at its work-group size on sm_90, and the
# inner loop's instruction mix (FFMA share, shared / global / local accesses), by
# scripts/device/ptx_report.py (ptxas -arch=sm_90 -v, nvdisasm). The driver's own -cl-nv-verbose
# logs found with the PTX (nvverbose/*.log of the kit's first.tgz) add its register and spill
# counts beside ours: where they differ, the driver compiled the PTX differently from ptxas here.
# Inputs: the kit's $OUT/first.tgz (or the $OUT folder holding it), folders of NAME.ptx, .ptx files.
# usage: scripts/device/analyse_ptx.sh [--all] [--markdown] [--check] [--keep DIR] INPUT...
#   --all      every kernel, not only the hot ones      --markdown  the table as Markdown
#   --check    exit 1 on a breach of the rules (as make gpu-static)
#   --keep DIR keep the cubins, SASS listings and ptxas logs in DIR (default: a temporary folder)
# Tools: PTXAS and NVDISASM when set, else the pinned pair of scripts/device/nvidia_tools.sh
# (installed into the cache when absent), else ptxas / nvdisasm on PATH or in /usr/local/cuda/bin.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
PY=${PYTHON:-python3}
opts=""
keep=""
while [ $# -gt 0 ]; do
  case $1 in
  --all | --markdown | --check) opts="$opts $1" ;;
  --keep) keep=${2:?--keep needs a folder}; shift ;;
  -*) sed -n '2,/^set -eu/p' "$0" | sed 's/^# \{0,1\}//' | grep -v '^set -eu' >&2; exit 2 ;;
  *) break ;;
  esac
  shift
done
[ $# -gt 0 ] || { echo "usage: scripts/device/analyse_ptx.sh [--all] [--markdown] [--check] [--keep DIR] first.tgz|DIR|FILE.ptx..." >&2; exit 2; }

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
work=${keep:-$tmp/work}
inputs=""
logs=""
for a in "$@"; do
  [ -d "$a" ] && [ -f "$a/first.tgz" ] && a=$a/first.tgz
  case $a in
  *.tgz | *.tar.gz)
    d=$tmp/x$(printf '%s' "$a" | cksum | cut -d' ' -f1)
    mkdir -p "$d" && tar -xzf "$a" -C "$d" || { echo "analyse_ptx: cannot unpack $a" >&2; exit 1; }
    for p in $(find "$d" -name '*.ptx' | sed 's|/[^/]*$||' | sort -u); do inputs="$inputs $p"; done
    for l in $(find "$d" -path '*nvverbose*' -name '*.log'); do logs="$logs --driver-log $l"; done
    ;;
  *) [ -e "$a" ] || { echo "analyse_ptx: $a: no such file or folder" >&2; exit 1; }; inputs="$inputs $a" ;;
  esac
done
[ -n "$inputs" ] || { echo "analyse_ptx: no .ptx files in $*" >&2; exit 1; }

ptxas=${PTXAS:-}
nvdisasm=${NVDISASM:-}
if [ -z "$ptxas" ] || [ -z "$nvdisasm" ]; then
  if tools=$(sh "$here/nvidia_tools.sh"); then
    ptxas=${ptxas:-$tools/ptxas} nvdisasm=${nvdisasm:-$tools/nvdisasm}
  else
    for d in $(echo "$PATH" | tr ':' ' ') /usr/local/cuda/bin; do
      [ -z "$ptxas" ] && [ -x "$d/ptxas" ] && ptxas=$d/ptxas
      [ -z "$nvdisasm" ] && [ -x "$d/nvdisasm" ] && nvdisasm=$d/nvdisasm
    done
  fi
fi
[ -n "$ptxas" ] || { echo "analyse_ptx: no ptxas (set PTXAS, or let scripts/device/nvidia_tools.sh install it)" >&2; exit 1; }
[ -n "$nvdisasm" ] || echo "analyse_ptx: no nvdisasm: no instruction mix" >&2
echo "analyse_ptx: $("$ptxas" --version | tail -n 1) ($ptxas)${logs:+; the driver's -cl-nv-verbose logs beside}"
# shellcheck disable=SC2086 # the option and input lists are split on purpose
"$PY" "$here/ptx_report.py" --ptxas "$ptxas" --nvdisasm "${nvdisasm:-}" --arch sm_90 --rules "$here/gpu_kernels.txt" \
  --work "$work" $opts $logs $inputs
