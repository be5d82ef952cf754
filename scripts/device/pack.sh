#!/bin/sh
# The GPU machine kit (docs/gpu.md): build smplpix here (Release, no MPI, build-kit/), then gather
# into one git-ignored folder (default .device-kit/) what scripts/device/run.sh needs on a
# machine that has glibc but none of our Debian packages:
#   DIR/build/   smplpix, smplpix-test-hooks, libsmplpix, the test and benchmark executables (with
#                probe_cl and, where CLBlast is installed, bench_clblast: the first step's probe and
#                baseline) and the CTestTestfile.cmake files (their build-tree paths rewritten to
#                DIR/build), stripped
#   DIR/lib/     every shared library they load that is not glibc's own (OpenEXR, Ceres and its
#                BLAS/LAPACK, cJSON, libpng, zlib, the ocl-icd loader libOpenCL.so.1, libstdc++,
#                libclblast.so.1 for bench_clblast only, ...)
#   DIR/manifest the source root the executables were built in (tests read tests/data from there:
#                run.sh links that path to the checkout it runs in), commit, glibc versions needed
# The kernels are built into libsmplpix; tests/data and data/ travel with the working tree.
# Carry DIR with the tree (device tool: carry [".device-kit"]); the tree plus DIR must stay under
# 64 MiB, so this fails when DIR is over SPX_KIT_MAX_MB (default 44).
# usage: scripts/device/pack.sh [DIR]   env: KIT_BUILD (build-kit), JOBS (nproc)
set -eu
cd "$(dirname "$0")/../.."
ROOT=$(pwd)
DIR=${1:-.device-kit}
KB=${KIT_BUILD:-build-kit}
JOBS=${JOBS:-$(nproc 2>/dev/null || echo 2)}
MAX_MB=${SPX_KIT_MAX_MB:-44}
case $DIR in /*) ;; *) DIR="$ROOT/$DIR" ;; esac
case $KB in /*) ;; *) KB="$ROOT/$KB" ;; esac

cmake -S . -B "$KB" -DCMAKE_BUILD_TYPE=Release -DSPX_MPI=OFF -DSPX_BENCH_LLVMPIPE=OFF >/dev/null
cmake --build "$KB" -j "$JOBS" >"$KB/pack-build.log" 2>&1 ||
  { tail -n 30 "$KB/pack-build.log" >&2; echo "pack.sh: build failed (log: $KB/pack-build.log)" >&2; exit 1; }

rm -rf "$DIR"
mkdir -p "$DIR/build/tests" "$DIR/build/benchmarks" "$DIR/lib"
cp -P "$KB"/libsmplpix.so* "$DIR/build/"
cp "$KB/smplpix" "$DIR/build/"
cp "$KB/smplpix-test-hooks" "$DIR/build/"
for f in "$KB"/tests/test_*; do [ -f "$f" ] && [ -x "$f" ] && cp "$f" "$DIR/build/tests/"; done
for f in "$KB"/benchmarks/bench_* "$KB"/benchmarks/probe_cl; do [ -f "$f" ] && [ -x "$f" ] && cp "$f" "$DIR/build/benchmarks/"; done
# ctest's files, with the build-tree paths pointing into the kit
for c in CTestTestfile.cmake tests/CTestTestfile.cmake benchmarks/CTestTestfile.cmake; do
  [ -f "$KB/$c" ] && sed "s|$KB|$DIR/build|g" "$KB/$c" >"$DIR/build/$c"
done
mkdir -p "$DIR/build/test-tmp"
(cd "$KB/test-tmp" && find . -type d) | (cd "$DIR/build/test-tmp" && xargs mkdir -p)
find "$DIR/build" -type f -perm -u+x -exec strip --strip-unneeded {} + 2>/dev/null || true

# the shared libraries: ldd's closure of every executable, minus glibc and the kit's own
is_glibc() {
  case $1 in
  libc.so.* | libm.so.* | libpthread.so.* | libdl.so.* | librt.so.* | ld-linux*.so.* | libresolv.so.* | \
    libutil.so.* | libmvec.so.* | libanl.so.* | libnss_*.so.* | linux-vdso.so.* | libsmplpix.so.*) return 0 ;;
  esac
  return 1
}
find "$DIR/build" -type f -perm -u+x | while read -r exe; do ldd "$exe" 2>/dev/null; done |
  awk '$2 == "=>" && $3 ~ /^\// { print $1, $3 }' | sort -u | while read -r name path; do
    is_glibc "$name" && continue
    [ -f "$DIR/lib/$name" ] || cp -L "$path" "$DIR/lib/$name"
  done
strip --strip-unneeded "$DIR"/lib/* 2>/dev/null || true
missing=$(LD_LIBRARY_PATH="$DIR/lib:$DIR/build" ldd "$DIR/build/smplpix" | grep 'not found' || true)
[ -z "$missing" ] || { echo "pack.sh: unresolved libraries: $missing" >&2; exit 1; }

glibc=$(find "$DIR/build" "$DIR/lib" -type f -exec objdump -T {} + 2>/dev/null |
  grep -oE 'GLIBC_[0-9]+\.[0-9]+' | sort -t. -k2 -n -u | tail -n 1)
{
  echo "source_root $ROOT"
  echo "kit $DIR"
  echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown)$(git diff --quiet 2>/dev/null || echo ' (with uncommitted changes)')"
  echo "packed $(date -u '+%Y-%m-%d %H:%M UTC') on $(uname -m), $(ldd --version | head -n 1)"
  echo "needs ${glibc:-GLIBC_?} or newer"
  echo "libs $(ls "$DIR/lib" | tr '\n' ' ')"
} >"$DIR/manifest"
mb=$(du -sm "$DIR" | cut -f1)
echo "pack.sh: $DIR: $mb MiB ($(ls "$DIR/build/tests" | wc -l) tests, $(ls "$DIR/build/benchmarks" | wc -l) benchmarks$([ -x "$DIR/build/benchmarks/bench_clblast" ] || echo ', no bench_clblast: libclblast-dev is not installed'), $(ls "$DIR/lib" | wc -l) libraries; needs ${glibc:-?})"
[ "$mb" -le "$MAX_MB" ] || { echo "pack.sh: $DIR is over $MAX_MB MiB: the tree and the kit must travel in 64 MiB" >&2; exit 1; }
