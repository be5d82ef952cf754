#!/usr/bin/python3
"""Build the CC0 default body (data/body/default_body.npz, SMPL .npz layout) from the
MakeHuman hm08 assets (CC0 1.0; see data/body/LICENSE-default-body.md).

Usage: tools/make_default_body.py MAKEHUMAN_HM08_DIR OUT.npz   (python3 + numpy only)

What it does:
  * vertices: the "body" vertex group of base.obj (helpers — joint cubes, eyes, teeth,
    tongue, clothing helpers — removed; body indices remapped), decimetres -> metres, Y up;
  * faces: body quads split into two triangles (a,b,c), (a,c,d); UVs kept as extra keys
    vt (Tx2) / ft (Fx3), compacted to the UVs the body uses;
  * shape space: NSAMPLES bodies sampled from the macro targets (targets/universal and
    targets/height: gender, age (adults, 25..90 years), muscle, weight, height drawn
    uniformly; MakeHuman's piecewise-linear macro weights), v_template = their mean,
    shapedirs = the first NCOMP principal components scaled by the standard deviation along
    them (so betas ~ N(0, 1) reproduce the sample spread);
  * skeleton: the 31-bone cmu_mb rig (names as in the CMU BVH files, except the finger bones),
    joint k = head of bone k = mean of its joint cube (or of the listed vertices for MEAN
    joints). Cube vertices are helpers, so each J_regressor row is an affine combination of
    the NNEAR body vertices nearest to the joint, fitted by least squares over all sampled
    bodies (the cubes move with the targets) with J_regressor @ v_template == cube mean
    imposed exactly and a small ridge towards uniform weights;
  * kintree_table from the rig parents (joints in depth-first order, children by name);
  * weights: weights.cmu_mb.json restricted to body vertices, rows renormalised;
  * posedirs: absent (no pose correctives).
  * joint_names: u1 bytes, names separated by '\\n'.
Deterministic (fixed seed). Prints the variance kept and the joint-regression errors.
"""
import gzip
import json
import os
import sys

import numpy as np

NSAMPLES = 400
NCOMP = 10
NNEAR = 200
LAMBDA = 1e-1  # ridge towards uniform weights (per sample-coordinate row scale: metres^2)
SEED = 20260121
HEIGHT_LO, HEIGHT_HI = 0.2, 0.8  # MakeHuman height slider range sampled (0.5 = the base)


def read_obj(path):
    v, vt, faces = [], [], []
    for line in open(path):
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("vt "):
            vt.append([float(x) for x in line.split()[1:3]])
        elif line.startswith("f "):
            corners = [c.split("/") for c in line.split()[1:]]
            faces.append(([int(c[0]) - 1 for c in corners], [int(c[1]) - 1 if len(c) > 1 and c[1] else -1 for c in corners]))
    return np.array(v), np.array(vt), faces


def group_indices(groups, name):
    idx = []
    for a, b in groups[name]:
        idx.extend(range(a, b + 1))
    return np.array(idx, dtype=np.int64)


def read_target(path, nv):
    d = np.zeros((nv, 3))
    tok = gzip.open(path, "rt").read().split()
    a = np.array(tok, dtype=np.float64).reshape(-1, 4)
    d[a[:, 0].astype(np.int64)] = a[:, 1:]
    return d


def lin3(x, names):
    """weights of three levels min/average/max for x in [0,1] (0.5 = average)"""
    lo, mid, hi = names
    if x < 0.5:
        return {lo: (0.5 - x) * 2, mid: 1 - (0.5 - x) * 2}
    return {mid: 1 - (x - 0.5) * 2, hi: (x - 0.5) * 2}


def age_weights(a):
    # MakeHuman age value: 0 -> 1 year, 0.1875 -> 11, 0.5 -> 25, 1 -> 90
    if a < 0.1875:
        return {"baby": 1 - a / 0.1875, "child": a / 0.1875}
    if a < 0.5:
        t = (a - 0.1875) / (0.5 - 0.1875)
        return {"child": 1 - t, "young": t}
    t = (a - 0.5) / 0.5
    return {"young": 1 - t, "old": t}


def macro_body(base, targets, g, a, m, w, h):
    out = base.copy()
    gw = {"female": 1 - g, "male": g}
    aw = age_weights(a)
    mw = lin3(m, ("minmuscle", "averagemuscle", "maxmuscle"))
    ww = lin3(w, ("minweight", "averageweight", "maxweight"))
    hw = {"minheight": max(0.0, (0.5 - h) * 2), "maxheight": max(0.0, (h - 0.5) * 2)}
    for gn, gv in gw.items():
        for an, av in aw.items():
            for mn, mv in mw.items():
                for wn, wv in ww.items():
                    base_w = gv * av * mv * wv
                    if base_w == 0:
                        continue
                    out += base_w * targets["universal-%s-%s-%s-%s" % (gn, an, mn, wn)]
                    for hn, hv in hw.items():
                        if hv:
                            out += base_w * hv * targets["%s-%s-%s-%s-%s" % (gn, an, mn, wn, hn)]
    return out


def fit_regressor_row(cand_samples, target_samples, cand_mean, target_mean, lam):
    """min sum_s |X_s w - t_s|^2 + lam |w - 1/k|^2  s.t.  sum w = 1, X_mean w = t_mean."""
    k = cand_samples.shape[1]
    # rows: samples x 3 coordinates
    X = cand_samples.transpose(0, 2, 1).reshape(-1, k)
    t = target_samples.reshape(-1)
    A = X.T @ X + lam * np.eye(k)
    b = X.T @ t + lam * np.full(k, 1.0 / k)
    C = np.vstack([np.ones((1, k)), cand_mean.T])  # 4 x k
    d = np.concatenate([[1.0], target_mean])
    KKT = np.block([[2 * A, C.T], [C, np.zeros((4, 4))]])
    rhs = np.concatenate([2 * b, d])
    sol = np.linalg.lstsq(KKT, rhs, rcond=None)[0]
    return sol[:k]


def main():
    src, out = sys.argv[1], sys.argv[2]
    V, VT, faces = read_obj(os.path.join(src, "base.obj"))
    nv_all = V.shape[0]
    groups = json.load(open(os.path.join(src, "basemesh_vertex_groups.json")))
    body = group_indices(groups, "body")
    remap = -np.ones(nv_all, dtype=np.int64)
    remap[body] = np.arange(len(body))
    # faces: body quads -> triangles
    f, ft = [], []
    for vi, ti in faces:
        if any(remap[i] < 0 for i in vi):
            continue
        for tri in ([0, 1, 2], [0, 2, 3]) if len(vi) == 4 else [[0, i, i + 1] for i in range(1, len(vi) - 1)]:
            f.append([remap[vi[c]] for c in tri])
            ft.append([ti[c] for c in tri])
    f = np.array(f, dtype=np.int32)
    ft = np.array(ft, dtype=np.int64)
    used_vt, ft_c = np.unique(ft.reshape(-1), return_inverse=True)
    assert used_vt.min() >= 0
    vt = VT[used_vt].astype(np.float32)
    ft_c = ft_c.reshape(-1, 3).astype(np.int32)

    # macro targets
    targets = {}
    for sub in ("universal", "height"):
        d = os.path.join(src, "targets", sub)
        for name in sorted(os.listdir(d)):
            if name.endswith(".target.gz"):
                targets[name[: -len(".target.gz")]] = read_target(os.path.join(d, name), nv_all)
    rng = np.random.default_rng(SEED)
    samples = np.empty((NSAMPLES, nv_all, 3))
    for s in range(NSAMPLES):
        g, a, m, w = rng.random(), 0.5 + 0.5 * rng.random(), rng.random(), rng.random()
        h = HEIGHT_LO + (HEIGHT_HI - HEIGHT_LO) * rng.random()
        samples[s] = macro_body(V, targets, g, a, m, w, h)
    samples *= 0.1  # decimetres -> metres
    mean_all = samples.mean(0)

    # PCA over body vertices
    X = samples[:, body].reshape(NSAMPLES, -1)
    mu = X.mean(0)
    U, S, Vt = np.linalg.svd(X - mu, full_matrices=False)
    var = S**2 / (NSAMPLES - 1)
    kept = var[:NCOMP].sum() / var.sum()
    shapedirs = (Vt[:NCOMP] * np.sqrt(var[:NCOMP])[:, None]).T.reshape(len(body), 3, NCOMP)
    v_template = mu.reshape(-1, 3)
    heights = samples[:, body, 1].max(1) - samples[:, body, 1].min(1)

    # skeleton
    rig = json.load(open(os.path.join(src, "rig.cmu_mb.json")))
    children = {}
    root = None
    for name, bone in rig.items():
        if bone["parent"]:
            children.setdefault(bone["parent"], []).append(name)
        else:
            root = name
    order = []
    stack = [root]
    while stack:
        n = stack.pop()
        order.append(n)
        stack.extend(sorted(children.get(n, []), reverse=True))
    K = len(order)
    index = {n: i for i, n in enumerate(order)}
    parents = np.array([index[rig[n]["parent"]] if rig[n]["parent"] else 2**32 - 1 for n in order], dtype=np.int64)
    kintree = np.stack([parents, np.arange(K, dtype=np.int64)])

    body_mean = mean_all[body]
    J_reg = np.zeros((K, len(body)))
    errs, rms = [], []
    for k, n in enumerate(order):
        head = rig[n]["head"]
        if head["strategy"] == "CUBE":
            cube = group_indices(groups, head["cube_name"])
        else:
            cube = np.array(head["vertex_indices"], dtype=np.int64)
        tgt_s = samples[:, cube].mean(1)  # NSAMPLES x 3
        tgt_m = mean_all[cube].mean(0)
        if all(remap[c] >= 0 for c in cube):  # joint given by body vertices: exact row
            J_reg[k, remap[cube]] = 1.0 / len(cube)
            errs.append(0.0)
            continue
        dist = np.linalg.norm(body_mean - tgt_m, axis=1)
        near = np.argsort(dist)[:NNEAR]
        cand_s = samples[:, body[near]]  # NSAMPLES x NNEAR x 3
        w = fit_regressor_row(cand_s, tgt_s, body_mean[near], tgt_m, lam=float(os.environ.get("SPX_LAM", LAMBDA)))
        J_reg[k, near] = w
        pred = np.einsum("snc,n->sc", cand_s, w)
        errs.append(np.sqrt(((pred - tgt_s) ** 2).sum(1)).max())
        rms.append(np.sqrt(((pred - tgt_s) ** 2).sum(1).mean()))
        if os.environ.get('VERBOSE'): print('  joint %-16s max err %.4f m over samples' % (n, errs[-1]))
    J_check = J_reg @ v_template

    # skinning weights
    wj = json.load(open(os.path.join(src, "weights.cmu_mb.json")))["weights"]
    W = np.zeros((len(body), K))
    for n, lst in wj.items():
        for i, x in lst:
            if remap[i] >= 0:
                W[remap[i], index[n]] += x
    W /= W.sum(1, keepdims=True)

    names = "\n".join(order).encode()
    np.savez_compressed(
        out,
        v_template=v_template.astype(np.float32),
        shapedirs=shapedirs.astype(np.float32),
        J_regressor=J_reg.astype(np.float32),
        weights=W.astype(np.float32),
        kintree_table=kintree,
        f=f,
        vt=vt,
        ft=ft_c,
        joint_names=np.frombuffer(names, dtype=np.uint8),
    )
    print("vertices %d, faces %d, uvs %d, joints %d, shape components %d" % (len(body), len(f), len(vt), K, NCOMP))
    print("variance kept by %d of %d components: %.4f%% (first: %s)" % (NCOMP, NSAMPLES, 100 * kept,
          ", ".join("%.2f%%" % (100 * v / var.sum()) for v in var[:NCOMP])))
    print("sample heights %.3f .. %.3f m, mean body height %.3f m" % (heights.min(), heights.max(),
          v_template[:, 1].max() - v_template[:, 1].min()))
    print("joint regression: RMS error over samples %.2e m (worst joint)" % max(rms))
    print("joint regression: max error over samples %.2e m, at the mean %.2e m" % (max(errs),
          np.abs(J_check - np.stack([mean_all[group_indices(groups, rig[n]['head']['cube_name'])].mean(0)
                 if rig[n]['head']['strategy'] == 'CUBE' else mean_all[rig[n]['head']['vertex_indices']].mean(0)
                 for n in order])).max()))
    print("J_regressor rows: max L1 norm %.2f (1 = convex combination), min weight %.3f" % (np.abs(J_reg).sum(1).max(), J_reg.min()))
    print("file size %d bytes" % os.path.getsize(out))


if __name__ == "__main__":
    main()
