#!/bin/sh
# Install the built library into a scratch prefix and move that tree elsewhere, then build and run a
# consumer against it twice (the installed tool must also find its library and data beside itself):
# through the CMake package (find_package(smplpix)) and through pkg-config.
set -eu
BUILD=$1
HERE=$(cd "$(dirname "$0")" && pwd)
WORK=$BUILD/test-tmp/install
rm -rf "$WORK"
mkdir -p "$WORK"
# install into one prefix, then move the tree: everything below must work from where it lies
cmake --install "$BUILD" --prefix "$WORK/prefix0" >/dev/null
mv "$WORK/prefix0" "$WORK/prefix"
LIBDIR=$(ls -d "$WORK"/prefix/lib*/ | head -1)
export LD_LIBRARY_PATH="$LIBDIR${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

cmake -S "$HERE" -B "$WORK/cmake-build" -DCMAKE_PREFIX_PATH="$WORK/prefix" >/dev/null
cmake --build "$WORK/cmake-build" >/dev/null
"$WORK/cmake-build/consumer"

PC=$(find "$WORK/prefix" -name smplpix.pc | head -1)
export PKG_CONFIG_PATH=$(dirname "$PC")
# the .pc finds its prefix from where it lies (${pcfiledir}): no edit needed for a scratch prefix
[ "$(pkg-config --variable=libdir smplpix | xargs realpath)" = "$(realpath "$LIBDIR")" ] ||
  { echo "install: smplpix.pc's libdir $(pkg-config --variable=libdir smplpix) is not $LIBDIR" >&2; exit 1; }
cc -std=c11 -o "$WORK/consumer-pc" "$HERE/consumer.c" $(pkg-config --cflags --libs smplpix)
"$WORK/consumer-pc"
# the installed tool runs without LD_LIBRARY_PATH (RUNPATH $ORIGIN/../lib) and reads the data
# installed beside it: an emptied copy of the default body must be the file it complains about
BODY="$WORK/prefix/share/smplpix/body/default_body.npz"
: > "$BODY"
msg=$(cd "$WORK" && env -u LD_LIBRARY_PATH -u SPX_DATA_DIR "$WORK/prefix/bin/smplpix" demo --out "$WORK/demo.png" 2>&1) &&
  { echo "install: the installed tool accepted an empty default body" >&2; exit 1; }
case "$msg" in
  *"$WORK/prefix/bin/../share/smplpix/body/default_body.npz"*) ;;
  *) echo "install: the installed tool did not read the data beside it: $msg" >&2; exit 1 ;;
esac
echo "install: CMake package and pkg-config consumers built and ran; the moved tool found its library and data"
