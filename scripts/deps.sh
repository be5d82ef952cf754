#!/bin/sh
# Install the Debian packages smplpix needs, if any are missing (as root; otherwise print the
# command to run). Used by `make demo` / `make test`; safe to run repeatedly.
set -eu
# jq: only for `make table1` (scripts/table1.sh reads synth.json with it)
# python3-numpy, python3-pytest, python3-venv: the Python package's tests (python/tests, pip install in a venv)
# libegl-dev, libgl-dev, libegl-mesa0, libgl1-mesa-dri: only for the benchmarks' Mesa llvmpipe peer (optional)
# libopenmpi-dev, openmpi-bin: `mpirun -np N smplpix train` (data-parallel; without them the tool trains on one process)
# oclgrind: `make oclgrind` (the GPU-class kernel paths under the Oclgrind simulator; CI)
# clang-15, libclc-15: `make gpu-static` (kernels to PTX with libclc's nvptx built-ins, LLVM 15 bitcode; CI)
# libclblast-dev: benchmarks only (bench_clblast, CLBlast's convolutions as a baseline; the device kit carries it)
PKGS="build-essential cmake pkg-config ocl-icd-opencl-dev opencl-c-headers pocl-opencl-icd \
libopenexr-dev libpng-dev zlib1g-dev libcjson-dev libceres-dev libeigen3-dev libnanoflann-dev clang \
libclang-rt-dev python3 python3-numpy python3-pytest python3-venv jq libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri \
libopenmpi-dev openmpi-bin oclgrind clang-15 libclc-15 libclblast-dev"
missing=""
for p in $PKGS; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
if [ "$(id -u)" -ne 0 ]; then
  echo "smplpix: missing Debian packages:$missing" >&2
  echo "smplpix: run as root, or: sudo apt-get install -y$missing" >&2
  exit 1
fi
echo "smplpix: installing$missing" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends $missing >/dev/null
