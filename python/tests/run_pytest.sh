#!/bin/sh
# ctest python_bindings: the pytest suite against the CMake build tree's library and CLI.
# usage: run_pytest.sh BUILD_DIR. Exit 77 (ctest SKIP) with a message when no Python with numpy
# and pytest is installed (Debian: python3-numpy python3-pytest; make deps installs them).
set -u
build=$(cd "$1" && pwd)
root=$(cd "$(dirname "$0")/../.." && pwd)
py=${SPX_PYTHON:-}
if [ -z "$py" ]; then
  for cand in /usr/bin/python3 python3; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c "import numpy, pytest" >/dev/null 2>&1; then py=$cand; break; fi
  done
fi
if [ -z "$py" ] || ! "$py" -c "import numpy, pytest" >/dev/null 2>&1; then
  echo "SKIP: no python3 with numpy and pytest (apt-get install python3-numpy python3-pytest, or set SPX_PYTHON)"
  exit 77
fi
lib=$(ls "$build"/libsmplpix.so 2>/dev/null || true)
[ -n "$lib" ] || { echo "run_pytest.sh: $build/libsmplpix.so not found (shared library build needed)" >&2; exit 1; }
export SMPLPIX_LIBRARY="$lib" SPX_TOOL="${SPX_TOOL:-$build/smplpix}" SPX_BUILD_DIR="$build"
export PYTHONPATH="$root/python${PYTHONPATH:+:$PYTHONPATH}"
cd "$root/python"
# exit 5 (no tests collected) is a failure too: ctest sees every non-zero status except 77
exec "$py" -m pytest -q -p no:cacheprovider --basetemp="$build/test-tmp/python_bindings" tests
