"""project / raster / UNet against the CLI's outputs on the shipped data, and bad input."""
import numpy as np
import pytest

import smplpix
from conftest import CAMERA, MESH, ORBIT


@pytest.fixture(scope="module")
def body():
    return smplpix.read_mesh(MESH)


@pytest.fixture(scope="module")
def colored(body, tmp_path_factory):
    """The shipped body with per-vertex colours, as a PLY both sides read."""
    d = tmp_path_factory.mktemp("colored")
    col = (0.5 + 0.5 * np.cos(body.vertices * 5)).astype(np.float32)
    smplpix.write_mesh(d / "c.ply", smplpix.Mesh(body.vertices, body.faces, col))
    m = smplpix.read_mesh(d / "c.ply")  # colours as stored (8-bit)
    return d / "c.ply", m


def test_project_matches_cli_white(ctx, cli, body, tmp_path):
    cli("project", "--mesh", MESH, "--camera", CAMERA, "--color", "white", "--out", tmp_path / "w.npy", "--quiet")
    img = smplpix.project(ctx, body.vertices, None, smplpix.Camera.load(CAMERA))
    assert img.shape == (1, 1, 308, 410, 4) and img.dtype == np.float32
    np.testing.assert_array_equal(img[0, 0], np.load(tmp_path / "w.npy"))
    assert 1000 < np.count_nonzero(img[0, 0, ..., 3] != 1) < 6890


def test_project_matches_cli_colors_and_camera_array(ctx, cli, colored, tmp_path):
    path, m = colored
    cli("project", "--mesh", path, "--camera", ORBIT, "--color", "mesh", "--out", tmp_path / "o.npy", "--quiet")
    cams = smplpix.Camera.load(ORBIT)
    img = smplpix.project(ctx, m.vertices, m.colors, cams)
    assert img.shape[:2] == (1, 8)
    for c in range(8):
        np.testing.assert_array_equal(img[0, c], np.load(tmp_path / f"o_{c:03d}.npy"))
    # batched vertex sets, nchw layout, winners, and the plain-C reference: all the same bits
    v2 = np.stack([m.vertices, m.vertices + np.float32(0.05)])
    out, win = smplpix.project(ctx, v2, m.colors, cams[:2], layout="nchw", return_winners=True)
    ref, rwin = smplpix.project(ctx, v2, m.colors, cams[:2], layout="nchw", return_winners=True, reference=True)
    assert out.shape == (2, 2, 4, cams[0].height, cams[0].width) and win.shape == (2, 2, cams[0].height, cams[0].width)
    np.testing.assert_array_equal(out, ref)
    np.testing.assert_array_equal(win, rwin)
    np.testing.assert_array_equal(out[0, :2].transpose(0, 2, 3, 1), img[0, :2])
    # winners say which vertex's colour each pixel holds
    hit = win[0, 0] >= 0
    np.testing.assert_array_equal(out[0, 0, :3][:, hit].T, m.colors[win[0, 0][hit]])


def test_raster_matches_cli(ctx, cli, colored, tmp_path):
    path, m = colored
    cam = smplpix.Camera.load(CAMERA)
    for aa in (1, 2):
        cli("raster", "--mesh", path, "--camera", CAMERA, "--aa", aa, "--out", tmp_path / f"r{aa}.npy", "--quiet")
        img = smplpix.raster(ctx, m.vertices, m.faces, m.colors, cam, aa=aa)
        np.testing.assert_array_equal(img[0], np.load(tmp_path / f"r{aa}.npy"))
    img, faces = smplpix.raster(ctx, m.vertices, m.faces, m.colors, cam, return_faces=True)
    ref, rfaces = smplpix.raster(ctx, m.vertices, m.faces, m.colors, cam, return_faces=True, reference=True)
    np.testing.assert_array_equal(faces, rfaces)
    np.testing.assert_array_equal(img[0][..., 3] != 1, faces[0] >= 0)
    back = smplpix.raster(ctx, m.vertices, m.faces, m.colors, cam, cull="back")
    assert np.count_nonzero(back[0][..., 3] != 1) <= np.count_nonzero(img[0][..., 3] != 1)


def test_unet_render_matches_cli(ctx, cli, body, tmp_path):
    net = smplpix.UNet.create(ctx, width=8, sigmoid=True, seed=7)
    assert net.width == 8 and net.sigmoid
    net.save(tmp_path / "n.safetensors")
    cam = smplpix.Camera(64, 48, [[60, 0, 32], [0, 60, 24], [0, 0, 1]], [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
                         [0, 0.83, 3])
    rgbd = smplpix.project(ctx, body.vertices, None, cam)[0, 0]
    smplpix.write_exr(tmp_path / "in.exr", rgbd)
    cli("render", "--checkpoint", tmp_path / "n.safetensors", "--input", tmp_path / "in.exr", "--out",
        tmp_path / "out.npy", "--quiet")
    want = np.load(tmp_path / "out.npy")
    got = net.render(rgbd)  # (H, W, 4) HWC in -> (H, W, 3)
    assert got.shape == (48, 64, 3)
    np.testing.assert_array_equal(got, want.reshape(got.shape) if want.ndim == 3 else want[0].transpose(1, 2, 0))
    batch = net.render(np.stack([rgbd.transpose(2, 0, 1)] * 2))  # (N, 4, H, W) -> (N, 3, H, W)
    np.testing.assert_array_equal(batch[1].transpose(1, 2, 0), got)
    # load what we saved: same weights, same picture
    again = smplpix.UNet.load(ctx, tmp_path / "n.safetensors")
    sd, sd2 = net.state_dict(), again.state_dict()
    assert "inc.double_conv.0.weight" in sd and sd.keys() == sd2.keys()
    for k in sd:
        np.testing.assert_array_equal(sd[k], sd2[k])
    np.testing.assert_array_equal(again.render(rgbd), got)
    again.close()
    net.close()


def test_bad_input_raises(ctx, body, tmp_path):
    cam = smplpix.Camera.load(CAMERA)
    with pytest.raises(ValueError, match="vertices"):
        smplpix.project(ctx, np.zeros((5, 2), np.float32), None, cam)
    with pytest.raises(ValueError, match="colors"):
        smplpix.project(ctx, body.vertices, np.zeros((3, 3), np.float32), cam)
    with pytest.raises(TypeError):
        smplpix.project(ctx, [["a", "b", "c"]], None, cam)
    with pytest.raises(ValueError, match="cameras"):
        smplpix.project(ctx, body.vertices, None, [])
    nan = body.vertices.copy()
    nan[3, 1] = np.nan
    _, win = smplpix.project(ctx, nan, None, cam, return_winners=True)  # a NaN vertex is dropped
    assert not np.any(win == 3)
    with pytest.raises(smplpix.SmplpixError) as e:  # an impossible camera is refused by the library
        smplpix.project(ctx, body.vertices, None, smplpix.Camera(0, 10, np.eye(3)))
    assert e.value.code in ("SPX_E_CAMERA", "SPX_E_ARG")
    with pytest.raises(ValueError, match="faces"):
        smplpix.raster(ctx, body.vertices, body.faces + 7000, None, cam)
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.UNet.load(ctx, tmp_path / "missing.safetensors")
    assert "missing.safetensors" in str(e.value)
    (tmp_path / "junk.safetensors").write_bytes(b"\x08\x00\x00\x00\x00\x00\x00\x00{}      ")
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.UNet.load(ctx, tmp_path / "junk.safetensors")
    assert "junk.safetensors" in str(e.value)
    with pytest.raises(smplpix.SmplpixError):
        smplpix.UNet.create(ctx, width=12)
    net = smplpix.UNet.create(ctx, width=8)
    with pytest.raises(smplpix.SmplpixError):  # below the 16x16 minimum
        net.render(np.ones((1, 4, 8, 8), np.float32))
    with pytest.raises(ValueError):
        net.render(np.ones((16, 16, 3), np.float32))
    net.close()
    with pytest.raises(ValueError, match="closed"):
        net.render(np.ones((1, 4, 16, 16), np.float32))


def test_render_points_on_device_equals_host_path(ctx, body):
    net = smplpix.UNet.create(ctx, width=8, seed=3)
    cams = [smplpix.Camera(40, 32, [[40, 0, 20], [0, 40, 16], [0, 0, 1]], [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
                           [0, 0.83, t]) for t in (3.0, 3.5)]
    v2 = np.stack([body.vertices, body.vertices * np.float32(0.9)])
    col = np.random.default_rng(0).random(body.vertices.shape, dtype=np.float32)
    dev = net.render_points(v2, col, cams)
    assert dev.shape == (2, 2, 3, 32, 40)
    host = net.render(smplpix.project(ctx, v2, col, cams, layout="nchw").reshape(4, 4, 32, 40))
    np.testing.assert_array_equal(dev.reshape(4, 3, 32, 40), host)
    net.close()


def test_inputs_converted_or_used_in_place(ctx, body):
    from smplpix._core import f32
    a = np.ascontiguousarray(body.vertices)
    assert f32(a, "a") is a  # float32 C order: no copy
    cam = smplpix.Camera.load(CAMERA)
    want = smplpix.project(ctx, body.vertices, None, cam)
    f64 = body.vertices.astype(np.float64)
    np.testing.assert_array_equal(smplpix.project(ctx, f64, None, cam), want)
    fortran = np.asfortranarray(body.vertices)
    np.testing.assert_array_equal(smplpix.project(ctx, fortran, None, cam), want)
    strided = np.concatenate([body.vertices, body.vertices], axis=1)[:, :3]  # a non-contiguous view
    assert not strided.flags.c_contiguous
    np.testing.assert_array_equal(smplpix.project(ctx, strided, None, cam), want)
    assert smplpix.project(ctx, body.vertices.tolist(), None, cam).shape == want.shape
