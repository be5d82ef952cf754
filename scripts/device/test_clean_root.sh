#!/bin/sh
# The GPU machine kit tested as that machine will run it, in a clean root (docs/gpu.md): a minimal
# Debian (debootstrap --variant=minbase, through the apt mirror of this machine) with none of
# smplpix's -dev packages, plus cmake (ctest; the GPU machine has it) and PoCL (only for this
# smoke test: the kit must not need it). The ocl-icd loader PoCL pulls in is removed again, so the
# kit's own libOpenCL.so.1 is the one loaded. Then, with the repository's tracked files and the
# kit copied to /repo (another path than the one the kit was built in, as on that machine):
#   1. every kit executable's libraries resolve to the kit or to glibc (ldd, LD_LIBRARY_PATH = kit)
#   2. scripts/device/run.sh with SPX_DEVICE=cpu and SPX_RUN_QUICK=1 (small benchmark sizes) runs
#      every step (limits x10: PoCL compiles every program cold on 2 shared cores); the first
#      step's sub-steps (the roofline, the program dump, the mma probe, the profiles, ours and
#      CLBlast's layer shapes), ctest
#      (SPX_CTEST_REGEX, default the device, sort, raster, LBS and upsampling tests, both columns)
#      and the benchmarks must end with rc=0; $OUT must hold summary.txt, first.tgz (with every
#      program's source), logs.tgz, bench.txt, ctest.txt; the summary the first step's sections
# Needs root (chroot, mount). The root is kept in SPX_CLEAN_ROOT (default /var/tmp/spx-clean-root)
# and reused; --fresh rebuilds it (a few minutes). Not run in CI (debootstrap and the run take
# ~10 minutes on 2 cores); run it after changing the kit: `make device-kit-test`.
# usage: scripts/device/test_clean_root.sh [--fresh] [KIT]   (KIT default .device-kit, from pack.sh)
set -eu
cd "$(dirname "$0")/../.."
ROOT=$(pwd)
fresh=0
[ "${1:-}" = --fresh ] && { fresh=1; shift; }
KIT=${1:-.device-kit}
CR=${SPX_CLEAN_ROOT:-/var/tmp/spx-clean-root}
REGEX=${SPX_CTEST_REGEX:-^test_(device|render_sort|render_raster|body_lbs|nn_upsample)(_gpu_paths)?$}
[ "$(id -u)" = 0 ] || { echo "test_clean_root: needs root (chroot)" >&2; exit 1; }
[ -x "$KIT/build/smplpix" ] || { echo "test_clean_root: no kit at $KIT (run scripts/device/pack.sh)" >&2; exit 1; }
command -v debootstrap >/dev/null || { echo "test_clean_root: debootstrap missing (apt-get install debootstrap)" >&2; exit 1; }

mirror=$(sed -n 's/^URIs: *//p' /etc/apt/sources.list.d/debian.sources 2>/dev/null | head -n 1)
[ -n "$mirror" ] || mirror=$(awk '$1 == "deb" { print $2; exit }' /etc/apt/sources.list 2>/dev/null)
mirror=${mirror:-http://deb.debian.org/debian}

if [ $fresh = 1 ] || [ ! -f "$CR/.ready" ]; then
  rm -rf "$CR"
  echo "test_clean_root: debootstrap bookworm (minbase) into $CR from $mirror ..."
  debootstrap --variant=minbase bookworm "$CR" "$mirror" >"$CR.debootstrap.log" 2>&1 ||
    { tail -n 20 "$CR.debootstrap.log" >&2; exit 1; }
  cp /etc/resolv.conf "$CR/etc/resolv.conf" 2>/dev/null || true
  chroot "$CR" sh -c 'export DEBIAN_FRONTEND=noninteractive; apt-get update -qq &&
    apt-get install -y -qq --no-install-recommends cmake pocl-opencl-icd >/dev/null &&
    dpkg --remove --force-depends ocl-icd-libopencl1 >/dev/null && apt-get clean' ||
    { echo "test_clean_root: installing cmake and PoCL into the root failed" >&2; exit 1; }
  touch "$CR/.ready"
fi
for p in ocl-icd-opencl-dev libopenexr-dev libceres-dev libcjson-dev libpng-dev ocl-icd-libopencl1; do
  if chroot "$CR" dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    echo "test_clean_root: $p is installed in $CR: not a clean root" >&2
    exit 1
  fi
done

# the tree as the device tool sends it (tracked and untracked-not-ignored files) plus the kit, at /repo
rm -rf "$CR/repo"
mkdir -p "$CR/repo"
git ls-files -z --cached --others --exclude-standard | xargs -0 tar -cf - | tar -xf - -C "$CR/repo"
mkdir -p "$CR/repo/.device-kit"
cp -a "$KIT/." "$CR/repo/.device-kit/"

mounted=""
cleanup() { for m in $mounted; do umount "$m" 2>/dev/null || true; done; }
trap cleanup EXIT
mount -t proc proc "$CR/proc" && mounted="$CR/proc"
mount --bind /dev "$CR/dev" && mounted="$CR/dev $mounted"
mount --bind /sys "$CR/sys" && mounted="$CR/sys $mounted" # PoCL's hwloc reads the CPU topology

echo "test_clean_root: 1. libraries of every kit executable (kit or glibc only)"
bad=$(chroot "$CR" sh -c 'cd /repo/.device-kit && export LD_LIBRARY_PATH=/repo/.device-kit/lib:/repo/.device-kit/build
  find build -type f -perm -u+x | while read -r e; do ldd "$e" | sed "s|^|$e: |"; done' |
  awk '/not found/ { print; next }
       $3 == "=>" && $4 ~ /^\// && $4 !~ /^\/repo\/\.device-kit\// &&
       $2 !~ /^(libc|libm|libpthread|libdl|librt|libresolv|libutil|libmvec)\.so/ { print }')
if [ -n "$bad" ]; then
  echo "$bad" | head -n 20 >&2
  echo "test_clean_root: FAIL: libraries outside the kit (above)" >&2
  exit 1
fi

echo "test_clean_root: 2. scripts/device/run.sh on PoCL (ctest -R '$REGEX')"
rm -rf "$ROOT/out/clean-root"
chroot "$CR" sh -c "cd /repo && SPX_DEVICE=cpu SPX_RUN_QUICK=1 SPX_CTEST_JOBS=2 SPX_RUN_BUDGET=${SPX_RUN_BUDGET:-3600} SPX_RUN_LIMIT_SCALE=${SPX_RUN_LIMIT_SCALE:-10} \
  SPX_CTEST_REGEX='$REGEX' OUT=/repo/out/device bash scripts/device/run.sh" >"$CR.run.log" 2>&1 || true
mkdir -p "$ROOT/out/clean-root"
cp -r "$CR/repo/out/device/." "$ROOT/out/clean-root/" 2>/dev/null || true
S=$ROOT/out/clean-root/summary.txt
[ -f "$S" ] || { tail -n 30 "$CR.run.log" >&2; echo "test_clean_root: FAIL: no summary.txt" >&2; exit 1; }
cat "$S"
fail=0
for s in env icd first_devices first_dump first_mma first_nvverbose first_eval first_train first_conv first_clblast \
  ctest latency unet project raster; do
  grep -q "^step $s: rc=0 " "$S" || { echo "test_clean_root: FAIL: step $s did not end with rc=0" >&2; fail=1; }
done
for want in '^peak [0-9]*:[0-9]* .* GFLOP/s fp32 FMA' '^-- inline PTX tensor cores: mma.sync tf32: rejected' \
  '^kernel profile (device time per command' '^roofline eval: ' '^roofline train: ' '^  4->64 3x3 ' '^first step: '; do
  grep -q "$want" "$S" || { echo "test_clean_root: FAIL: summary.txt has no line matching: $want" >&2; fail=1; }
done
tar -tzf "$ROOT/out/clean-root/first.tgz" 2>/dev/null | grep -q 'first/programs/conv2d_lds.cl.opts' ||
  { echo "test_clean_root: FAIL: first.tgz lacks the programs' sources" >&2; fail=1; }
grep -q "^100% tests passed" "$S" || { echo "test_clean_root: FAIL: ctest did not pass" >&2; fail=1; }
grep -q "^icd: .*libpocl" "$S" || { echo "test_clean_root: FAIL: PoCL was not found by run.sh" >&2; fail=1; }
n=$(ls "$ROOT/out/clean-root" | wc -l)
[ "$n" -le 8 ] || { echo "test_clean_root: FAIL: $n files in \$OUT (at most 8 come back)" >&2; fail=1; }
for f in summary.txt first.tgz logs.tgz bench.txt ctest.txt; do
  [ -s "$ROOT/out/clean-root/$f" ] || { echo "test_clean_root: FAIL: \$OUT/$f missing or empty" >&2; fail=1; }
done
[ $fail = 0 ] && echo "test_clean_root: PASS (results in out/clean-root/)"
exit $fail
