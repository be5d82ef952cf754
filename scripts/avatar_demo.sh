#!/bin/sh
# make docs-avatar: docs/avatar.png, the README's picture of a person's own avatar in motion.
#   1. the avatar: $AVATAR when given, else synthetic subject 0 of `smplpix synth --seed 21` made into
#      an avatar at the default settings (out/avatar-demo/, reused when it is there);
#   2. avatar_tool frames: frames 2240, 2280, ... (8, a third of a second apart) of data/mocap/01_01.bvh,
#      from the clip's last fifth, the stretch whose poses `avatar` holds out of training,
#      each framed on the posed person: the avatar, and the per-vertex raster of the same vertices;
#   3. table1_tool grid: the avatar's 8 frames above the raster's, docs/avatar.png.
# Environment: AVATAR (an avatar.safetensors), AVATAR_BUILD (default build). Bad input: one line, exit 1.
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
build=${AVATAR_BUILD:-$root/build}
die() { echo "avatar_demo: error: $*" >&2; exit 1; }
for t in "$build/smplpix" "$build/benchmarks/avatar_tool" "$build/benchmarks/table1_tool"; do
  [ -x "$t" ] || die "$t: not built (make build, with SPX_BUILD_BENCHMARKS=ON)"
done
out=$root/out/avatar-demo
mkdir -p "$out"
avatar=${AVATAR:-$out/avatar/avatar.safetensors}
if [ ! -f "$avatar" ]; then
  [ -z "${AVATAR:-}" ] || die "$AVATAR: no such file (AVATAR)"
  [ -f "$out/synth/synth.json" ] || "$build/smplpix" synth --subjects 1 --views 1 --seed 21 --out "$out/synth" --quiet
  resume=""
  [ -f "$out/avatar/work/run.txt" ] && resume=--resume
  nice -n 10 "$build/smplpix" avatar --scan "$out/synth/s000/scan.ply" --out "$out/avatar" $resume
fi
rm -rf "$out/frames" && mkdir -p "$out/frames"
"$build/benchmarks/avatar_tool" frames --avatar "$avatar" --bvh "$root/data/mocap/01_01.bvh" --first 2240 --step 40 \
  --count 8 --size 192x256 --out "$out/frames"
"$build/benchmarks/table1_tool" grid --out "$root/docs/avatar.png" --cols 8 "$out"/frames/avatar_*.png "$out"/frames/raster_*.png
echo "wrote $root/docs/avatar.png (top: the avatar; bottom: the per-vertex raster of the same vertices)"
