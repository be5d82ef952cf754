"""Contexts and the objects made from them are freed cleanly, repeatedly, in any order."""
import gc
import os
import subprocess
import sys

import numpy as np

import smplpix
from conftest import BODY


def rss_mib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def cycle(device):
    with smplpix.Context(device=device) as ctx:
        if device is not False:
            cam = smplpix.Camera(32, 32, [[30, 0, 16], [0, 30, 16], [0, 0, 1]], t=[0, 0, 2])
            smplpix.project(ctx, np.zeros((10, 3), np.float32), None, cam)
            smplpix.UNet.create(ctx, width=8)  # dropped without close(): freed with the context


def test_create_destroy_does_not_leak():
    for device in (False, "cpu"):
        n = 1000 if device is False else 20  # a leaked context would add > 15 MiB
        for _ in range(3):
            cycle(device)
        gc.collect()
        before = rss_mib()
        for _ in range(n):
            cycle(device)
        gc.collect()
        grown = rss_mib() - before
        assert grown < 8, f"device={device}: RSS grew by {grown:.1f} MiB over {n} create/destroy cycles"


def test_close_order_and_idempotence():
    ctx = smplpix.Context("cpu")
    body = smplpix.BodyModel.load(ctx, BODY)
    net = smplpix.UNet.create(ctx, width=8)
    ctx.close()  # closes the body model and the network first
    ctx.close()
    net.close()
    body.close()
    assert repr(ctx) == "<smplpix.Context closed>"
    try:
        smplpix.project(ctx, np.zeros((3, 3), np.float32), None, smplpix.Camera(8, 8, np.eye(3)))
    except ValueError as e:
        assert "closed" in str(e)
    else:
        raise AssertionError("a closed context was used")


def test_interpreter_exit_with_live_objects():
    """Objects still alive at exit are freed by their finalizers, children before the context."""
    code = ("import smplpix, numpy as np\n"
            "ctx = smplpix.Context('cpu')\n"
            f"b = smplpix.BodyModel.load(ctx, {BODY!r})\n"
            "n = smplpix.UNet.create(ctx, width=8)\n"
            "v, j = b.forward()\n"
            "print('ok', v.shape)\n")
    pkg_parent = os.path.dirname(os.path.dirname(smplpix.__file__))  # the smplpix under test
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([pkg_parent, os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and "ok (13380, 3)" in r.stdout, r.stderr
