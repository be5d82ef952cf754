"""BodyModel (against the SMPL equations in numpy and the plain-C reference) and register()
(against `smplpix register`)."""
import json
import os
import sys

import numpy as np
import pytest

import smplpix
from conftest import BODY, MESH


# the Rodrigues formula of the C golden (tests/data/body/make_lbs_golden.py), numpy only
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "data", "body"))
from make_lbs_golden import rodrigues  # noqa: E402


def lbs_numpy(z, pose, betas, trans):
    """The SMPL forward as body.h states it (no posedirs in the shipped model)."""
    vt = z["v_template"].astype(np.float64)
    sd = z["shapedirs"].astype(np.float64)[:, :, :len(betas)]
    Jr = z["J_regressor"].astype(np.float64)
    W = z["weights"].astype(np.float64)
    par = z["kintree_table"][0].astype(np.int64)
    v_shaped = vt + sd @ betas
    J = Jr @ v_shaped
    K = J.shape[0]
    A = [None] * K
    for k in range(K):
        T = np.eye(4)
        T[:3, :3] = rodrigues(pose[k])
        T[:3, 3] = J[k] - (J[par[k]] if k else 0)
        A[k] = T if k == 0 else A[par[k]] @ T
    G = np.stack(A)
    joints = G[:, :3, 3] + trans
    G[:, :3, 3] -= np.einsum("kij,kj->ki", G[:, :3, :3], J)
    T = np.einsum("nk,kij->nij", W, G)
    v = np.einsum("nij,nj->ni", T[:, :3, :3], v_shaped) + T[:, :3, 3] + trans
    return v, joints


def test_body_forward(ctx):
    body = smplpix.BodyModel.load(ctx, BODY)
    z = np.load(BODY)
    assert (body.nv, body.nj, body.nbetas) == (13380, 31, 10)
    np.testing.assert_array_equal(body.faces, z["f"])
    np.testing.assert_array_equal(body.v_template, z["v_template"])
    assert body.joint_names is not None and len(body.joint_names) == 31
    rng = np.random.default_rng(3)
    pose = rng.normal(0, 0.3, (31, 3))
    betas = rng.normal(0, 1, 4)
    trans = np.array([0.1, -0.2, 0.3])
    want_v, want_j = lbs_numpy(z, pose, betas, trans)
    ref_v, ref_j = body.forward_ref(pose, betas, trans)
    np.testing.assert_allclose(ref_v, want_v, atol=1e-9)
    np.testing.assert_allclose(ref_j, want_j, atol=1e-9)
    v, j = body.forward(pose, betas, trans)
    assert v.shape == (13380, 3) and v.dtype == np.float32 and j.shape == (31, 3)
    np.testing.assert_allclose(v, want_v, atol=2e-5)
    np.testing.assert_allclose(j, want_j, atol=2e-5)
    # batched: (B, K*3) poses, (B, S) shapes, (B, 3) translations
    pb = np.stack([pose.ravel(), np.zeros(93)])
    vb, jb = body.forward(pb, np.stack([betas, betas]), np.stack([trans, trans]))
    assert vb.shape == (2, 13380, 3)
    np.testing.assert_array_equal(vb[0], v)
    np.testing.assert_allclose(vb[1], lbs_numpy(z, np.zeros((31, 3)), betas, trans)[0], atol=2e-5)
    rest, _ = body.forward()
    np.testing.assert_allclose(rest, z["v_template"], atol=1e-6)
    with pytest.raises(ValueError, match="pose"):
        body.forward(np.zeros(5))
    with pytest.raises(ValueError, match="shape"):
        body.forward(None, np.zeros(11))
    with pytest.raises(ValueError, match="NaN"):
        body.forward(None, None, [0, np.nan, 0])
    body.close()
    with pytest.raises(ValueError, match="closed"):
        body.forward()


def test_body_load_errors(ctx, tmp_path):
    z = dict(np.load(BODY))
    del z["weights"]
    np.savez(tmp_path / "noweights.npz", **z)
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.BodyModel.load(ctx, tmp_path / "noweights.npz")
    assert "noweights.npz" in str(e.value) and "weights" in str(e.value)
    (tmp_path / "x.npz").write_bytes(b"PK\x03\x04garbage")
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.BodyModel.load(ctx, tmp_path / "x.npz")
    assert "x.npz" in str(e.value)


def test_register_matches_cli(ctx, cli, tmp_path):
    cli("register", "--scan", MESH, "--model", BODY, "--out", tmp_path / "reg.ply", "--params", tmp_path / "reg.json",
        "--stages", "rigid")
    scan = smplpix.read_mesh(MESH)
    body = smplpix.BodyModel.load(ctx, BODY)
    steps = []
    r = smplpix.register(ctx, body, scan.vertices, scan.colors, scan.faces, stages=["rigid"], threads=1,
                         progress=steps.append, params_json=tmp_path / "py.json")
    assert r.stages == ["rigid"] and steps and steps[0]["stage"] == "rigid"
    assert r.vertices.shape == (13380, 3) and r.faces.shape == (26756, 3)
    cli_mesh = smplpix.read_mesh(tmp_path / "reg.ply")
    np.testing.assert_array_equal(r.vertices, cli_mesh.vertices)
    p = json.load(open(tmp_path / "reg.json"))
    q = json.load(open(tmp_path / "py.json"))
    for k in p:
        if k not in ("model", "stages", "seconds", "stage_seconds"):
            assert json.dumps(p[k]) == json.dumps(q[k]) or k.endswith("seconds"), k
    np.testing.assert_allclose(r.sim_R @ r.sim_R.T, np.eye(3), atol=1e-9)
    # a progress callback that raises: the exception comes back, the interpreter survives
    def boom(_):
        raise KeyboardInterrupt("stop")
    with pytest.raises(KeyboardInterrupt):
        smplpix.register(ctx, body, scan.vertices, stages="rigid", progress=boom, max_points_rigid=500)
    with pytest.raises(smplpix.SmplpixError) as e:
        smplpix.register(ctx, body, scan.vertices[:5], stages="rigid")
    assert "\n" not in str(e.value)
    with pytest.raises(TypeError, match="unknown option"):
        smplpix.register(ctx, body, scan.vertices, nonsense=1)
    with pytest.raises(ValueError, match="stages"):
        smplpix.register(ctx, body, scan.vertices, stages=["wiggle"])
    body.close()
