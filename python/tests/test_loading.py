"""The second way to use the package: an installed libsmplpix found through pkg-config."""
import os
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT


def test_installed_library_through_pkg_config(tmp_path):
    build = os.environ.get("SPX_BUILD_DIR")
    if not build or not shutil.which("cmake") or not shutil.which("pkg-config"):
        pytest.skip("needs SPX_BUILD_DIR (set by ctest's python_bindings), cmake and pkg-config")
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", build, "--prefix", str(prefix)], check=True, capture_output=True)
    env = {k: v for k, v in os.environ.items() if k != "SMPLPIX_LIBRARY"}
    env["PKG_CONFIG_PATH"] = str(prefix / "lib" / "pkgconfig") + os.pathsep + env.get("PKG_CONFIG_PATH", "")
    env["PYTHONPATH"] = os.path.join(ROOT, "python")  # the source package: no library inside it
    code = "import smplpix; print(smplpix.LIBRARY_PATH); print(smplpix.Context(device=False))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(str(prefix)), r.stdout
