"""Depth images through the bindings: read_depth (spx_depth_read) against the values written,
depth_person and depth_points on a rendered body in a synthetic room, register() with the camera,
and the library's one-line refusals."""
import numpy as np
import pytest

import smplpix
from conftest import BODY, MESH


def _scene(ctx):
    """human_woman.obj seen by a 160x120 camera 2.4 m in front, standing on a floor 3 m from a wall."""
    mesh = smplpix.read_mesh(MESH)
    v = mesh.vertices
    c = (v.min(0) + v.max(0)) / 2
    cam = smplpix.Camera.look_at(160, 120, 130.0, eye=(c[0], c[1] + 0.1, c[2] + 2.4), target=c)
    img, faces = smplpix.raster(ctx, v, mesh.faces, None, [cam], return_faces=True)
    body = np.where(faces[0] >= 0, img[0][..., 3], 0).astype(np.float32)
    # the room: the floor under the feet and a wall 3 m behind the body, by ray casting
    j, i = np.mgrid[0:cam.height, 0:cam.width]
    y = (j + 0.5 - cam.K[1, 2]) / cam.K[1, 1]
    x = (i + 0.5 - cam.K[0, 2]) / cam.K[0, 0]
    rays = np.stack([x, y, np.ones_like(x)], -1) @ cam.R  # world directions (camera depth 1)
    eye = cam.eye()
    t_floor = np.where(rays[..., 1] < -1e-9, (v[:, 1].min() - eye[1]) / np.minimum(rays[..., 1], -1e-9), np.inf)
    t_wall = np.where(rays[..., 2] < -1e-9, (c[2] - 3.0 - eye[2]) / np.minimum(rays[..., 2], -1e-9), np.inf)
    room = np.minimum(t_floor, t_wall).astype(np.float32)
    raw = np.where(body > 0, body, np.where(np.isfinite(room), room, 0)).astype(np.float32)
    return mesh, cam, body, raw


def test_read_depth_formats(tmp_path):
    z = np.full((30, 40), 2.0, np.float32) + np.linspace(0, 0.5, 40, dtype=np.float32)
    z[:5, :5] = 0
    z[10, 10] = np.nan
    smplpix.write_npy(tmp_path / "d.npy", z)
    got = smplpix.read_depth(tmp_path / "d.npy")
    want = np.where(np.isnan(z), 0, z)
    np.testing.assert_array_equal(got, want)
    rgbd = np.ones((30, 40, 4), np.float32)
    rgbd[..., 3] = np.where(want > 0, want, 1)
    smplpix.write_exr(tmp_path / "d.exr", rgbd)
    np.testing.assert_array_equal(smplpix.read_depth(tmp_path / "d.exr"), want)
    cam = smplpix.Camera(40, 30, [[32, 0, 20], [0, 32, 15], [0, 0, 1]])
    assert smplpix.read_depth(tmp_path / "d.npy", camera=cam).shape == (30, 40)
    wide = smplpix.Camera(40, 30, [[32, 0, 39], [0, 32, 15], [0, 0, 1]])
    with pytest.raises(smplpix.SmplpixError, match="principal point"):
        smplpix.read_depth(tmp_path / "d.npy", camera=wide)
    smplpix.write_npy(tmp_path / "mm.npy", z * 1000)
    with pytest.raises(smplpix.SmplpixError, match="look like millimetres"):
        smplpix.read_depth(tmp_path / "mm.npy")
    smplpix.write_npy(tmp_path / "flat.npy", np.full((30, 40), 2.0, np.float32))
    with pytest.raises(smplpix.SmplpixError, match="one flat value"):
        smplpix.read_depth(tmp_path / "flat.npy")


def test_depth_person_points_register(ctx):
    mesh, cam, body, raw = _scene(ctx)
    person, rep = smplpix.depth_person(raw, cam)
    assert rep["nplanes"] >= 1 and rep["kept"] == int((person > 0).sum())
    kept_body = ((person > 0) & (body > 0)).sum() / (body > 0).sum()
    assert kept_body > 0.95 and ((person > 0) & (body == 0)).sum() <= 0.02 * rep["kept"]
    pts, cols = smplpix.depth_points(person, cam)
    assert cols is None and pts.shape == (rep["kept"], 3)
    bm = smplpix.BodyModel.load(ctx, BODY)
    r = smplpix.register(ctx, bm, pts, stages=["rigid", "pose"], threads=2, view_eyes=[cam.eye()])
    assert r.vertices.shape[0] == bm.nv and r.stages == ["rigid", "pose"]
    with pytest.raises(ValueError, match="point_view"):
        smplpix.register(ctx, bm, pts, view_eyes=[cam.eye(), cam.eye()], point_view=np.zeros(3, np.int32))
    with pytest.raises(smplpix.SmplpixError, match="no person near the centre"):
        smplpix.depth_person(np.where(body > 0, 0, raw), cam)
