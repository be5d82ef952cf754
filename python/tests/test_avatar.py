"""smplpix.Avatar (smplpix/avatar.h) on an avatar the CLI makes from a synthetic scan at tiny sizes
(stand-in perceptual networks: a width-4 VGG16 from tests/data and a random AlexNet LPIPS written
here): its info, colours and faces, posing, rendering equal to `smplpix render --avatar`, and bad
input."""
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import smplpix
from conftest import DATA, ROOT

sys.path.insert(0, os.path.join(ROOT, "tools"))
from spx_safetensors import st_save  # noqa: E402

CLIP = os.path.join(DATA, "mocap", "01_01.bvh")


def _lpips_weights(path):
    """An AlexNet LPIPS file with random weights (the names and shapes smplpix/metrics.h reads)."""
    rng = np.random.default_rng(1)
    shapes = {"net.slice1.0": (64, 3, 11, 11), "net.slice2.3": (192, 64, 5, 5), "net.slice3.6": (384, 192, 3, 3),
              "net.slice4.8": (256, 384, 3, 3), "net.slice5.10": (256, 256, 3, 3)}
    t = []
    for name, s in shapes.items():
        a = np.sqrt(6.0 / np.prod(s[1:]))
        t.append((name + ".weight", rng.uniform(-a, a, s).astype(np.float32)))
        t.append((name + ".bias", rng.uniform(-0.1, 0.1, s[:1]).astype(np.float32)))
    for i, s in enumerate(shapes.values()):
        t.append((f"lin{i}.model.1.weight", rng.uniform(0, 0.2, (1, s[0], 1, 1)).astype(np.float32)))
    t.append(("scaling_layer.shift", np.array([-.030, -.088, -.188], np.float32).reshape(1, 3, 1, 1)))
    t.append(("scaling_layer.scale", np.array([.458, .448, .450], np.float32).reshape(1, 3, 1, 1)))
    st_save(path, t)


@pytest.fixture(scope="module")
def made(tool, tmp_path_factory):
    d = tmp_path_factory.mktemp("avatar")
    w = d / "cache" / "weights"
    w.mkdir(parents=True)
    shutil.copy(os.path.join(ROOT, "tests", "data", "vgg", "vgg16_w4.safetensors"), w / "vgg16.safetensors")
    _lpips_weights(str(w / "lpips_alex.safetensors"))
    env = dict(os.environ, SPX_CACHE_DIR=str(d / "cache"))

    def run(*args, check=True):
        r = subprocess.run([tool, *map(str, args)], capture_output=True, text=True, env=env, cwd=d)
        assert not check or r.returncode == 0, f"smplpix {' '.join(map(str, args))}: {r.stderr}"
        return r
    run("synth", "--subjects", 1, "--views", 1, "--size", "64x48", "--texture-size", 256, "--seed", 9, "--out", "synth",
        "--quiet")
    betas = json.load(open(d / "synth" / "synth.json"))["subjects"][0]["betas"]
    model = os.path.join(DATA, "body", "default_body.npz")
    with smplpix.Context(device=False) as c0:
        body = smplpix.BodyModel.load(c0, model)
        nv, nj, template = body.nv, body.nj, body.v_template
    reg = {"format": "smplpix-registration", "version": 1, "model": model, "nv": nv, "nj": nj,
           "unit_scale": 1, "similarity": {"scale": 1, "R": [1, 0, 0, 0, 1, 0, 0, 0, 1], "t": [0, 0, 0]},
           "body_scale": 1, "betas": betas, "pose": [0.0] * (3 * nj), "trans": [0, 0, 0],
           "template": template.reshape(-1).astype(float).tolist()}
    json.dump(reg, open(d / "reg.json", "w"))
    run("avatar", "--scan", "synth/s000/scan.ply", "--registration", "reg.json", "--out", "A", "--views", 2,
        "--heldout", 1, "--size", "32x48", "--steps", 2, "--quiet")
    return d, run


def test_avatar_info_pose_render(ctx, made):
    d, run = made
    with smplpix.Avatar.load(ctx, d / "A" / "avatar.safetensors") as a:
        i = a.info
        assert i["vertices"] == 13380 and i["subdivide"] == 0 and i["image_size"] == (32, 48) and i["net_width"] == 16
        assert i["model_path"].endswith("default_body.npz") and i["train_cpu_seconds"] > 0
        assert a.colors.shape == (13380, 3) and 0 <= a.colors.min() and a.colors.max() <= 1
        assert a.faces.shape == (26756, 3)
        reg = a.registration
        assert reg["pose"].shape == (i["joints"], 3) and reg["body_scale"] == 1
        v0 = a.pose_vertices()
        assert v0.shape == (13380, 3) and np.isfinite(v0).all()
        pose = np.zeros((i["joints"], 3))
        pose[0] = [0, 1.0, 0]
        v1 = a.pose_vertices(pose, [0, 0, 0])
        assert not np.allclose(v0, v1)
        cam = smplpix.Camera.look_at(32, 48, 55.0, eye=[0.2, 0.9, 3.0], target=[0, 0.9, 0])  # the size it was trained at
        smplpix.Camera.save(d / "cam.json", cam)
        rgb, inp = a.render(cam, with_input=True)
        assert rgb.shape == (48, 32, 3) and inp.shape == (48, 32, 4) and np.count_nonzero(inp[..., 3] != 1) > 50
        run("render", "--avatar", "A/avatar.safetensors", "--camera", "cam.json", "--out", "r.npy", "--quiet")
        np.testing.assert_array_equal(rgb, np.load(d / "r.npy"))
        big = smplpix.Camera.look_at(40, 56, 60.0, eye=[0.2, 0.9, 3.0], target=[0, 0.9, 0])
        smplpix.Camera.save(d / "big.json", big)
        r = run("render", "--avatar", "A/avatar.safetensors", "--camera", "big.json", "--out", "b.npy", check=False)
        assert r.returncode == 1 and "trained at 32x48" in r.stderr
        run("render", "--avatar", "A/avatar.safetensors", "--camera", "big.json", "--out", "b.npy", "--any-size")
        np.testing.assert_array_equal(a.render(big), np.load(d / "b.npy"))
        with pytest.raises(ValueError):
            a.pose_vertices(np.zeros(5))


def test_avatar_bad_files(ctx, made, tmp_path):
    d, _ = made
    with pytest.raises(smplpix.SmplpixError, match="not an avatar file"):
        u = smplpix.UNet.create(ctx, 8)
        u.save(tmp_path / "net.safetensors")
        smplpix.Avatar.load(ctx, tmp_path / "net.safetensors")
    with pytest.raises(smplpix.SmplpixError, match="nothere"):
        smplpix.Avatar.load(ctx, tmp_path / "nothere.safetensors")
