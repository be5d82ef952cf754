#!/bin/sh
# ctest python_pip_install: what docs/python.md tells Python users to run, in a fresh venv:
#   python3 -m venv V && V/bin/pip install ./python
# then the pytest suite against the installed wheel (its own libsmplpix, not the build tree's).
# usage: pip_install.sh BUILD_DIR. Exit 77 (ctest SKIP) with a message when python3-venv / pip
# are missing or PyPI (scikit-build-core, numpy, pytest) cannot be reached.
set -u
build=$(cd "$1" && pwd)
root=$(cd "$(dirname "$0")/../.." && pwd)
py=${SPX_PYTHON:-/usr/bin/python3}
command -v "$py" >/dev/null 2>&1 || py=python3
venv="$build/python-venv"
rm -rf "$venv"
if ! "$py" -m venv "$venv" >/dev/null 2>&1 || [ ! -x "$venv/bin/pip" ]; then
  echo "SKIP: '$py -m venv' with pip is not available (apt-get install python3-venv)"
  exit 77
fi
if ! "$venv/bin/pip" download -q --no-deps -d "$venv/probe" scikit-build-core >/dev/null 2>&1; then
  echo "SKIP: PyPI is not reachable (pip install ./python needs scikit-build-core and numpy from it)"
  exit 77
fi
set -e
export CMAKE_BUILD_PARALLEL_LEVEL="${CMAKE_BUILD_PARALLEL_LEVEL:-2}"
"$venv/bin/pip" install -q --config-settings=build-dir="$build/python-wheel" "$root/python" pytest
cd "$build"  # not the source tree: the import must find the installed package
"$venv/bin/python" -c "import smplpix, sys; p = smplpix.LIBRARY_PATH; print('installed smplpix', smplpix.version(), 'library', p); sys.exit(0 if p.startswith('$venv') else 1)"
SPX_TOOL="$build/smplpix" "$venv/bin/python" -m pytest -q -p no:cacheprovider --rootdir="$root/python" \
  --basetemp="$build/test-tmp/python_pip_install" "$root/python/tests"
