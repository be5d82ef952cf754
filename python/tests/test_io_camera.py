"""Files and cameras through the bindings, against the CLI's outputs and numpy."""
import json
import os

import numpy as np
import pytest

import smplpix
from conftest import CAMERA, MESH, ORBIT


def test_camera_load_matches_json():
    cams = smplpix.Camera.load(CAMERA)
    raw = json.load(open(CAMERA))
    raw = raw if isinstance(raw, list) else [raw]
    assert len(cams) == len(raw)
    for c, r in zip(cams, raw):
        assert (c.width, c.height) == (r["width"], r["height"])
        np.testing.assert_array_equal(c.K, np.array(r["K"], float))
        np.testing.assert_array_equal(c.R, np.array(r["R"], float))
        np.testing.assert_array_equal(c.t, np.array(r["t"], float))


def test_camera_round_trip(tmp_path):
    cams = smplpix.Camera.load(ORBIT)
    assert len(cams) == 8
    smplpix.Camera.save(tmp_path / "c.json", cams)
    back = smplpix.Camera.load(tmp_path / "c.json")
    for a, b in zip(cams, back):
        np.testing.assert_allclose(a.K, b.K, rtol=1e-15)
        np.testing.assert_allclose(a.R, b.R, rtol=1e-15)
        np.testing.assert_allclose(a.t, b.t, rtol=1e-15)
    # to_json is the contract's object; from_json parses it back through the library
    again = smplpix.Camera.from_json(json.dumps([c.to_json() for c in cams]))
    np.testing.assert_array_equal(again[3].R, cams[3].R)


def test_camera_look_at_is_valid():
    c = smplpix.Camera.look_at(64, 48, 60.0, eye=(0, 1, 3), target=(0, 1, 0))
    c.validate()
    np.testing.assert_allclose(c.R @ c.R.T, np.eye(3), atol=1e-12)
    # the target lands at the principal point
    p = c.K @ (c.R @ np.array([0, 1, 0.0]) + c.t)
    np.testing.assert_allclose(p[:2] / p[2], [32, 24], atol=1e-9)


def test_camera_errors_name_the_problem(tmp_path):
    bad = {"width": 10, "height": 10, "K": [[10, 0, 5], [0, 10, 5], [0, 0, 1]],
           "R": [[1, 0, 0], [0, 1, 0], [0, 0, 2]], "t": [0, 0, 0]}
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.Camera.from_json(json.dumps([bad]), name="cams.json")
    assert "cams.json" in str(e.value) and "[0].R" in str(e.value) and e.value.code == "SPX_E_CAMERA"
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.Camera.from_json("{\"width\": 3", name="broken.json")
    assert "broken.json" in str(e.value) and e.value.code == "SPX_E_FORMAT"
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.Camera.load(tmp_path / "missing.json")
    assert "missing.json" in str(e.value) and e.value.code == "SPX_E_IO"
    with pytest.raises(smplpix.SmplpixError):
        smplpix.Camera(10, 10, np.eye(3), R=np.diag([1.0, 1.0, -1.0])).validate()  # det < 0


def test_images_against_cli(cli, tmp_path):
    out = tmp_path / "p.exr"
    cli("project", "--mesh", MESH, "--camera", CAMERA, "--out", out, "--png", tmp_path / "p.png",
        "--npy", tmp_path / "p.npy", "--quiet")
    exr = smplpix.read_exr(out)
    npy = smplpix.read_npy(tmp_path / "p.npy")
    png = smplpix.read_png(tmp_path / "p.png")
    assert exr.shape == (308, 410, 4) and exr.dtype == np.float32
    np.testing.assert_array_equal(exr, npy)
    np.testing.assert_array_equal(npy, np.load(tmp_path / "p.npy"))
    assert png.shape == (308, 410, 3)
    np.testing.assert_allclose(png, np.clip(exr[..., :3], 0, 1), atol=0.5 / 255 + 1e-6)


def test_image_round_trips(tmp_path):
    rng = np.random.default_rng(1)
    img = rng.random((17, 23, 4), dtype=np.float32)
    smplpix.write_exr(tmp_path / "a.exr", img)
    np.testing.assert_array_equal(smplpix.read_exr(tmp_path / "a.exr"), img)
    smplpix.write_png(tmp_path / "a.png", img[..., :3])
    np.testing.assert_allclose(smplpix.read_png(tmp_path / "a.png"), img[..., :3], atol=0.5 / 255 + 1e-6)
    smplpix.write_png(tmp_path / "g.png", img[..., 0])
    assert smplpix.read_png(tmp_path / "g.png").shape == (17, 23, 1)
    for a in (img, np.arange(24, dtype=np.int64).reshape(2, 3, 4), np.array([1.5, 2.5])):
        smplpix.write_npy(tmp_path / "a.npy", a)
        back = smplpix.read_npy(tmp_path / "a.npy")
        assert back.dtype == a.dtype
        np.testing.assert_array_equal(back, a)
        np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), a)


def test_mesh_read_write(tmp_path):
    m = smplpix.read_mesh(MESH)
    assert m.vertices.shape == (6890, 3) and m.faces.shape == (13776, 3)
    col = (0.5 + 0.5 * np.sin(m.vertices * 7)).astype(np.float32)
    smplpix.write_mesh(tmp_path / "c.ply", smplpix.Mesh(m.vertices, m.faces, col))
    back = smplpix.read_mesh(tmp_path / "c.ply")
    np.testing.assert_array_equal(back.vertices, m.vertices)
    np.testing.assert_array_equal(back.faces, m.faces)
    np.testing.assert_allclose(back.colors, col, atol=0.5 / 255 + 1e-6)  # PLY colours are 8-bit


def test_io_errors(tmp_path):
    (tmp_path / "bad.exr").write_bytes(b"not an exr file at all")
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 9\n")
    (tmp_path / "bad.npy").write_bytes(b"\x93NUMPY\x01\x00\x10\x00{'descr': '<f4'")
    for fn, name in ((smplpix.read_exr, "bad.exr"), (smplpix.read_mesh, "bad.obj"), (smplpix.read_npy, "bad.npy"),
                     (smplpix.read_png, "bad.exr")):
        with pytest.raises(smplpix.SmplpixError) as e:
            fn(tmp_path / name)
        assert name in str(e.value), str(e.value)
        assert "\n" not in str(e.value)
    with pytest.raises(ValueError):
        smplpix.write_exr(tmp_path / "x.exr", np.zeros((4, 4, 2), np.float32))
    with pytest.raises(TypeError):
        smplpix.write_npy(tmp_path / "x.npy", np.array(["a", "b"]))
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.write_png(tmp_path / "no" / "such" / "dir.png", np.zeros((4, 4, 3), np.float32))
    assert "dir.png" in str(e.value)
    assert not os.path.exists(tmp_path / "x.exr")
