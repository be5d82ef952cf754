"""Shared fixtures: the repository's data, the smplpix CLI (compared against), one device context."""
import os
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DATA = os.path.join(ROOT, "data")
MESH = os.path.join(DATA, "body", "human_woman.obj")
BODY = os.path.join(DATA, "body", "default_body.npz")
CAMERA = os.path.join(DATA, "cameras", "default.json")
ORBIT = os.path.join(DATA, "cameras", "orbit8.json")


def _tool():
    t = os.environ.get("SPX_TOOL") or os.path.join(ROOT, "build", "smplpix")
    return t if os.path.isfile(t) and os.access(t, os.X_OK) else None


@pytest.fixture(scope="session")
def tool():
    t = _tool()
    if t is None:
        pytest.skip("the smplpix CLI is not built (set SPX_TOOL)")
    return t


@pytest.fixture(scope="session")
def cli(tool):
    """Run the CLI; fail the test with its stderr when it fails."""
    def run(*args):
        r = subprocess.run([tool, *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, f"smplpix {' '.join(map(str, args))}: exit {r.returncode}: {r.stderr}"
        return r.stdout
    return run


@pytest.fixture(scope="session")
def ctx():
    import smplpix
    c = smplpix.Context(device=os.environ.get("SPX_DEVICE") or None)
    yield c
    c.close()
