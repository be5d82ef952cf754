#!/bin/sh
# Install the built library into a scratch prefix, then build and run a consumer against it twice:
# through the CMake package (find_package(smplpix)) and through pkg-config.
set -eu
BUILD=$1
HERE=$(cd "$(dirname "$0")" && pwd)
WORK=$BUILD/test-tmp/install
rm -rf "$WORK"
mkdir -p "$WORK"
cmake --install "$BUILD" --prefix "$WORK/prefix" >/dev/null
LIBDIR=$(ls -d "$WORK"/prefix/lib*/ | head -1)
export LD_LIBRARY_PATH="$LIBDIR${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

cmake -S "$HERE" -B "$WORK/cmake-build" -DCMAKE_PREFIX_PATH="$WORK/prefix" >/dev/null
cmake --build "$WORK/cmake-build" >/dev/null
"$WORK/cmake-build/consumer"

PC=$(find "$WORK/prefix" -name smplpix.pc | head -1)
export PKG_CONFIG_PATH=$(dirname "$PC")
# the .pc was generated for the configured prefix; point it at the scratch prefix
sed -i "s|^prefix=.*|prefix=$WORK/prefix|" "$PC"
cc -std=c11 -o "$WORK/consumer-pc" "$HERE/consumer.c" $(pkg-config --cflags --libs smplpix)
"$WORK/consumer-pc"
echo "install: CMake package and pkg-config consumers built and ran"
