#!/bin/sh
# The GPU-class paths of the kernel tests (SPX_TUNE_CLASS=gpu: local-memory convolution and
# Winograd, the GEMM engine, the radix-sort projection, the per-pixel rasterizer, the work-group
# reductions of the norms and losses; SPX_OCLGRIND_TESTS names others) under
# Oclgrind, the OpenCL simulator that checks every memory access and barrier: data races
# (--data-races), reads and writes out of bounds, barrier divergence; with NVIDIA's
# limits (48 KiB of local memory, work-groups of at most 1024). By default each test runs with
# --quick (only the first and last work-group of every launch execute, which keeps the run to
# minutes): the tests' own comparisons then fail and are not looked at, and neither are
# out-of-bounds reports, since a later launch then reads buffers (histograms, offsets) that the
# skipped work-groups never wrote; what fails the check is a data race or barrier divergence in
# Oclgrind's log. SPX_OCLGRIND_FULL=1 runs every work-group (slow: tens of minutes on 2 cores)
# and then fails on any report. (Oclgrind's --uninitialized is left out: the Debian build stops on
# the LLVM `freeze` instruction.)
# usage: scripts/device/oclgrind_check.sh [BUILD_DIR]   env: SPX_OCLGRIND_TESTS (names),
#        SPX_OCLGRIND_TIMEOUT (s per test, 900), SPX_OCLGRIND_FULL=1
set -u
cd "$(dirname "$0")/../.."
BUILD=${1:-build}
command -v oclgrind >/dev/null || { echo "oclgrind_check: oclgrind not found (apt-get install oclgrind)" >&2; exit 1; }
# the tests of the kernels that share local memory across a work-group (where races live);
# test_render_project is left out of the default list (over 10 minutes under Oclgrind even with
# --quick: SPX_OCLGRIND_TESTS=test_render_project runs it); its radix sort is test_render_sort's
TESTS=${SPX_OCLGRIND_TESTS:-test_nn_conv2d_lds test_nn_conv2d_gemm test_nn_conv2d_winograd_lds test_render_sort
test_render_raster test_nn_batchnorm test_nn_instnorm test_nn_loss}
LIMIT=${SPX_OCLGRIND_TIMEOUT:-900}
quick=--quick
[ "${SPX_OCLGRIND_FULL:-0}" = 1 ] && quick=
out=$BUILD/oclgrind
rm -rf "$out"
mkdir -p "$out/cache" "$out/tmp"
fails=0
for t in $TESTS; do
  [ -x "$BUILD/tests/$t" ] || { echo "oclgrind_check: $BUILD/tests/$t not built" >&2; fails=$((fails + 1)); continue; }
  mkdir -p "$out/tmp/$t"
  t0=$(date +%s)
  SPX_TUNE_CLASS=gpu SPX_CACHE_DIR="$out/cache" SPX_TEST_TMP="$out/tmp/$t" SPX_TOOL="$BUILD/smplpix" \
    timeout -k 10 "$LIMIT" oclgrind $quick --data-races --max-errors 100 --log "$out/$t.log" --local-mem-size 49152 \
    --max-wgsize 1024 --num-threads 1 "$BUILD/tests/$t" >"$out/$t.out" 2>&1
  rc=$?
  dt=$(($(date +%s) - t0))
  if [ $rc = 124 ] || [ $rc = 137 ]; then
    echo "oclgrind_check: $t: TIMEOUT after ${LIMIT}s" >&2
    fails=$((fails + 1))
  elif { [ -z "$quick" ] && [ -s "$out/$t.log" ]; } || grep -qiE 'data race|divergence' "$out/$t.log"; then
    echo "oclgrind_check: $t: Oclgrind reported errors (${dt}s; $out/$t.log):" >&2
    grep -v '^[[:space:]]*$' "$out/$t.log" | head -n 12 >&2
    fails=$((fails + 1))
  elif [ -s "$out/$t.log" ]; then
    echo "oclgrind_check: $t: clean of races and divergence (${dt}s); $(grep -c '^Invalid' "$out/$t.log") out-of-bounds reports under --quick, not counted ($out/$t.log)"
  elif grep -q 'OCLGRIND FATAL' "$out/$t.out"; then
    echo "oclgrind_check: $t: Oclgrind stopped (${dt}s; $out/$t.out)" >&2
    fails=$((fails + 1))
  else
    echo "oclgrind_check: $t: clean (${dt}s)"
  fi
done
echo "oclgrind_check: $(echo $TESTS | wc -w) tests, $fails with findings (logs in $out/)"
[ $fails = 0 ]
