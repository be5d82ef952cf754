#!/bin/sh
# NVIDIA's assembler and disassembler for the offline PTX checks (make gpu-static, analyse_ptx.sh),
# pinned, into ${SPX_CACHE_DIR:-~/.cache/smplpix}/nvidia-tools/ as `make weights` installs its
# networks: ptxas from the PyPI wheel nvidia-cuda-nvcc-cu12 12.9.86 (CUDA 12.9, PTX ISA up to 8.8)
# and nvdisasm from nvidia-cuda-nvdisasm 13.2.78 (the disassembler is published only as a CUDA 13
# wheel; it reads CUDA 12 cubins), each wheel fetched with `pip download --no-deps
# --require-hashes` and its sha256 checked again here, the one binary taken out of it, the pair
# checked to run. A run with both binaries matching SHA256SUMS and
# VERSION does nothing. SPX_NVIDIA_WHEELS=DIR uses the two wheel files in DIR instead of
# downloading (checked the same way). PYTHON picks the interpreter.
# Prints the folder holding ptxas and nvdisasm on stdout. Exit status:
#   0 installed or up to date
#   3 not available here (no pip, no network, PyPI unreachable, not x86-64): one line on stderr;
#     the callers skip their step
#   1 an error: a wheel whose sha256 differs from the pin, a wheel without the binary, a binary that
#     does not run, an unwritable cache; one line on stderr, the cache as it was
set -eu
NVCC_WHEEL=nvidia_cuda_nvcc_cu12-12.9.86-py3-none-manylinux2010_x86_64.manylinux_2_12_x86_64.whl
NVCC_SHA256=5d6a0d32fdc7ea39917c20065614ae93add6f577d840233237ff08e9a38f58f0
DIS_WHEEL=nvidia_cuda_nvdisasm-13.2.78-py3-none-manylinux2014_x86_64.manylinux_2_17_x86_64.whl
DIS_SHA256=b4ebcd3c5046bf8039ac52675b9dbefd843600969649ecaab0a42b0713a61dae
VERSION="nvidia-cuda-nvcc-cu12==12.9.86 nvidia-cuda-nvdisasm==13.2.78"

die() {
  echo "nvidia-tools: $*" >&2
  exit 1
}
skip() {
  echo "nvidia-tools: $*" >&2
  exit 3
}

. "$(cd "$(dirname "$0")/../.." && pwd)/scripts/pypi_cache.sh"
cache=$(spx_cache_root) || die "neither SPX_CACHE_DIR nor HOME is set: no cache directory"
dest=$cache/nvidia-tools
sha() { sha256sum "$1" | cut -d' ' -f1; }

if [ -f "$dest/SHA256SUMS" ] && [ "$(cat "$dest/VERSION" 2>/dev/null)" = "$VERSION" ] &&
  (cd "$dest" && sha256sum --quiet -c SHA256SUMS >/dev/null 2>&1); then
  echo "$dest"
  exit 0
fi
[ "$(uname -m)" = x86_64 ] || skip "the pinned wheels are x86-64 builds; this is $(uname -m)"

py=""
for p in ${PYTHON:-} python3 /usr/bin/python3; do
  if command -v "$p" >/dev/null 2>&1 && "$p" -c "import zipfile" >/dev/null 2>&1; then
    py=$p
    break
  fi
done
[ -n "$py" ] || skip "no python3 (it unpacks the wheels)"
mkdir -p "$cache" 2>/dev/null || die "$cache: cannot create the directory"
tmp=$(mktemp -d "$cache/.nvidia-tools.XXXXXX") || die "$cache: cannot create a temporary directory"
trap 'rm -rf "$tmp"' EXIT
trap 'rm -rf "$tmp"; exit 130' INT TERM

if [ -n "${SPX_NVIDIA_WHEELS:-}" ]; then
  wheels=$SPX_NVIDIA_WHEELS
  for w in $NVCC_WHEEL $DIS_WHEEL; do [ -f "$wheels/$w" ] || die "$wheels/$w: no such file (SPX_NVIDIA_WHEELS)"; done
else
  pip=$(spx_pip "$py" "$tmp") || skip "no python3 with pip, nor a venv with one (apt-get install python3-pip or python3-venv)"
  {
    echo "nvidia-cuda-nvcc-cu12==12.9.86 --hash=sha256:$NVCC_SHA256"
    echo "nvidia-cuda-nvdisasm==13.2.78 --hash=sha256:$DIS_SHA256"
  } >"$tmp/req.txt"
  if ! "$pip" -m pip download --no-deps --only-binary :all: --require-hashes -r "$tmp/req.txt" -d "$tmp/dl" \
    >"$tmp/pip.log" 2>&1; then
    grep -q "DO NOT MATCH THE HASHES" "$tmp/pip.log" &&
      die "pip download: a wheel's sha256 differs from the pin in scripts/device/nvidia_tools.sh: $(grep -m1 -A3 'DO NOT MATCH' "$tmp/pip.log" | tail -n 1 | sed 's/^ *//')"
    why=$(grep -E "^ERROR|^error" "$tmp/pip.log" | head -n 1)
    skip "pip download $VERSION failed: ${why:-$(tail -n 1 "$tmp/pip.log")}"
  fi
  wheels=$tmp/dl
fi
[ "$(sha "$wheels/$NVCC_WHEEL")" = "$NVCC_SHA256" ] ||
  die "$wheels/$NVCC_WHEEL: sha256 $(sha "$wheels/$NVCC_WHEEL"), expected $NVCC_SHA256"
[ "$(sha "$wheels/$DIS_WHEEL")" = "$DIS_SHA256" ] ||
  die "$wheels/$DIS_WHEEL: sha256 $(sha "$wheels/$DIS_WHEEL"), expected $DIS_SHA256"

mkdir "$tmp/out"
"$py" - "$wheels/$NVCC_WHEEL" nvidia/cuda_nvcc/bin/ptxas "$wheels/$DIS_WHEEL" nvidia/cu13/bin/nvdisasm "$tmp/out" <<'EOF' ||
import os, sys, zipfile
a = sys.argv[1:]
for wheel, member in ((a[0], a[1]), (a[2], a[3])):
    with zipfile.ZipFile(wheel) as z:
        data = z.read(member)
    path = os.path.join(a[4], os.path.basename(member))
    with open(path, "wb") as f:
        f.write(data)
    os.chmod(path, 0o755)
EOF
  die "cannot unpack ptxas / nvdisasm from the wheels (not zip files, or the binaries are missing)"
for b in ptxas nvdisasm; do
  "$tmp/out/$b" --version >/dev/null 2>&1 || die "$tmp/out/$b --version fails: not a binary this machine runs"
done
(cd "$tmp/out" && sha256sum ptxas nvdisasm) >"$tmp/out/SHA256SUMS" || die "cannot hash the binaries"
echo "$VERSION" >"$tmp/out/VERSION"
rm -rf "$dest.old"
[ ! -e "$dest" ] || mv "$dest" "$dest.old" || die "$dest: cannot move the old copy aside"
mv "$tmp/out" "$dest" || die "$dest: cannot move into place"
rm -rf "$dest.old"
echo "nvidia-tools: installed $VERSION in $dest${SPX_NVIDIA_WHEELS:+ (from $SPX_NVIDIA_WHEELS)}" >&2
echo "$dest"
