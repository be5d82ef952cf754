"""python/examples/render_body.py runs and its projection equals the CLI's (--color normal)."""
import os
import subprocess
import sys

import numpy as np

import smplpix
from conftest import CAMERA, MESH, ROOT


def test_example_script(ctx, cli, tmp_path):
    smplpix.UNet.create(ctx, width=8, sigmoid=True, seed=2).save(tmp_path / "n.safetensors")
    pkg_parent = os.path.dirname(os.path.dirname(smplpix.__file__))
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([pkg_parent, os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, os.path.join(ROOT, "python", "examples", "render_body.py"), "--checkpoint",
                        str(tmp_path / "n.safetensors"), "--out", str(tmp_path / "ex")],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "pixels hold a vertex" in r.stdout
    cli("project", "--mesh", MESH, "--camera", CAMERA, "--color", "normal", "--out", tmp_path / "n.png", "--quiet")
    np.testing.assert_array_equal(smplpix.read_png(tmp_path / "ex" / "projection.png"),
                                  smplpix.read_png(tmp_path / "n.png"))
    render = smplpix.read_png(tmp_path / "ex" / "render.png")
    assert render.shape == (308, 410, 3)
