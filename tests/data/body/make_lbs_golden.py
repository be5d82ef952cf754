#!/usr/bin/python3
"""Golden data for tests/test_body_lbs.c: the SMPL forward equations written with numpy only,
in the 4x4 homogeneous form (independent of the C code's 3x4 formulation).

  v_shaped = v_template + shapedirs @ betas;  J = J_regressor @ v_shaped
  R_k = exp([r_k]x) (Rodrigues);  v_posed = v_shaped + posedirs @ vec(R_1..R_{K-1} - I)
  A_k = A_parent [[R_k, J_k - J_parent], [0, 1]];  G_k = A_k [[I, -J_k], [0, 1]]
  v = (sum_k w_ik G_k) [v_posed_i; 1] + trans;  joints = A_k[:3, 3] + trans

Usage: make_lbs_golden.py OUTDIR [DEFAULT_BODY.npz]
Writes OUTDIR/small_model.npz (N=50, K=5, S=4, with posedirs; J_regressor float64, kintree
int64 with root 2^32-1, f uint32 — the real SMPL dtypes) and OUTDIR/small_golden.npz; with a
default body, also OUTDIR/default_golden.npz (a random pose of that model, float64 results).
"""
import sys
import numpy as np


def rodrigues(r):
    t = np.linalg.norm(r)
    if t < 1e-12:
        return np.eye(3)
    k = r / t
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(t) * Kx + (1 - np.cos(t)) * Kx @ Kx


def f32(a):
    """The library stores every model array as float32; compute from exactly those values."""
    return np.asarray(a).astype(np.float32).astype(np.float64)


def lbs(m, betas, pose, trans):
    vt = f32(m["v_template"])
    N = vt.shape[0]
    sd = f32(m["shapedirs"])[:, :, : len(betas)]
    v_shaped = vt + np.einsum("ncs,s->nc", sd, betas)
    J = f32(m["J_regressor"]) @ v_shaped
    K = J.shape[0]
    parents = m["kintree_table"][0].astype(np.int64)
    R = np.stack([rodrigues(pose[k]) for k in range(K)])
    v_posed = v_shaped.copy()
    if "posedirs" in m:
        pf = (R[1:] - np.eye(3)).reshape(-1)
        v_posed += np.einsum("ncp,p->nc", f32(m["posedirs"]), pf)
    A = np.zeros((K, 4, 4))
    for k in range(K):
        local = np.eye(4)
        local[:3, :3] = R[k]
        p = parents[k]
        is_root = k == 0
        local[:3, 3] = J[k] if is_root else J[k] - J[p]
        A[k] = local if is_root else A[p] @ local
    G = np.zeros_like(A)
    for k in range(K):
        unrest = np.eye(4)
        unrest[:3, 3] = -J[k]
        G[k] = A[k] @ unrest
    W = f32(m["weights"])
    T = np.einsum("nk,kab->nab", W, G)
    vh = np.concatenate([v_posed, np.ones((N, 1))], axis=1)
    verts = np.einsum("nab,nb->na", T, vh)[:, :3] + trans
    joints = A[:, :3, 3] + trans
    return verts, joints


def small_model(rng):
    N, K, S = 50, 5, 4
    parents = np.array([2**32 - 1, 0, 1, 0, 3], dtype=np.int64)
    v = rng.normal(size=(N, 3)) * 0.3
    w = rng.random((N, K)) ** 3
    w /= w.sum(1, keepdims=True)
    jr = rng.random((K, N))
    jr[jr < 0.7] = 0
    jr /= jr.sum(1, keepdims=True)
    f = np.array([[i, (i + 1) % N, (i + 7) % N] for i in range(N)], dtype=np.uint32)
    return {
        "v_template": v.astype(np.float32),
        "shapedirs": (rng.normal(size=(N, 3, S)) * 0.05).astype(np.float32),
        "posedirs": (rng.normal(size=(N, 3, 9 * (K - 1))) * 0.02).astype(np.float32),
        "J_regressor": jr.astype(np.float64),
        "weights": w.astype(np.float32),
        "kintree_table": np.stack([parents, np.arange(K, dtype=np.int64)]),
        "f": f,
    }


def main():
    out = sys.argv[1]
    rng = np.random.default_rng(20260121)
    m = small_model(rng)
    np.savez_compressed(out + "/small_model.npz", **m)
    betas = rng.normal(size=4)
    pose = rng.normal(size=(5, 3)) * 0.6
    trans = rng.normal(size=3)
    verts, joints = lbs(m, betas, pose, trans)
    np.savez(out + "/small_golden.npz", betas=betas, pose=pose, trans=trans, verts=verts, joints=joints)
    if len(sys.argv) > 2:
        d = dict(np.load(sys.argv[2]))
        K = d["J_regressor"].shape[0]
        nb = min(10, d["shapedirs"].shape[2])
        betas = rng.normal(size=nb)
        pose = rng.normal(size=(K, 3)) * 0.3
        trans = np.array([0.1, -0.2, 0.3])
        verts, joints = lbs(d, betas, pose, trans)
        np.savez_compressed(out + "/default_golden.npz", betas=betas, pose=pose, trans=trans,
                            verts=verts.astype(np.float32), joints=joints)


if __name__ == "__main__":
    main()
