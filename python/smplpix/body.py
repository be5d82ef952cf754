"""Parametric body models in the SMPL .npz layout (smplpix/body.h)."""
from __future__ import annotations

import ctypes
import weakref
from typing import List, Optional, Tuple

import numpy as np

from . import _lib as L
from ._core import Context, PathLike, _path, carray, dptr, f32, fptr


def _free(ctx: Context, m: L.spx_body_model, live: list) -> None:  # ctx kept alive until freed
    if live[0]:
        L.spx_body_free(ctypes.byref(m))
        live[0] = False


class BodyModel:
    """A body model (spx_body_model): v_template (N, 3), shapedirs (N, 3, S), posedirs,
    J_regressor (K, N), weights (N, K), parents (K,), faces (F, 3). Real SMPL / SMPL-H / SMPL-X
    .npz files load unchanged. forward() skins on the context's device (float32); forward_ref()
    is the plain-C double-precision reference."""

    def __init__(self, ctx: Context, m: L.spx_body_model):
        self.ctx = ctx
        self._m = m
        self._live = [True]
        self._fin = weakref.finalize(self, _free, ctx, m, self._live)
        ctx._adopt(self)

    @classmethod
    def load(cls, ctx: Context, path: PathLike) -> "BodyModel":
        """spx_body_load: an .npz in the SMPL layout; errors name the file, key and shape."""
        m = L.spx_body_model()
        ctx.check(L.spx_body_load(ctx.ptr, _path(path), ctypes.byref(m)))
        return cls(ctx, m)

    def close(self) -> None:
        self._fin()

    @property
    def model(self) -> L.spx_body_model:
        if not self._live[0]:
            raise ValueError("smplpix: the body model is closed")
        return self._m

    nv = property(lambda self: self.model.nv, doc="number of vertices N")
    nj = property(lambda self: self.model.nj, doc="number of joints K")
    nbetas = property(lambda self: self.model.nbetas, doc="number of shape directions S")

    @property
    def faces(self) -> np.ndarray:
        m = self.model
        return carray(m.faces, m.nf * 3, np.int32).reshape(m.nf, 3)

    @property
    def v_template(self) -> np.ndarray:
        m = self.model
        return carray(m.v_template, m.nv * 3, np.float32).reshape(m.nv, 3)

    @property
    def parents(self) -> np.ndarray:
        return carray(self.model.parents, self.model.nj, np.int32)

    @property
    def joint_names(self) -> Optional[List[str]]:
        m = self.model
        if not m.joint_names:
            return None
        return [m.joint_names[k].decode() for k in range(m.nj)]

    def _params(self, pose, shape, trans, dtype):
        """Normalise (pose, shape, trans) to (B, K*3), (B, S'), (B, 3) arrays of dtype."""
        m = self.model
        pose_a = None if pose is None else np.asarray(pose, dtype=dtype)
        shape_a = None if shape is None else np.asarray(shape, dtype=dtype)
        trans_a = None if trans is None else np.asarray(trans, dtype=dtype)
        sizes = []  # batch sizes of the batched parameters
        if pose_a is not None and (pose_a.ndim == 3 or (pose_a.ndim == 2 and pose_a.shape != (m.nj, 3))):
            sizes.append(pose_a.shape[0])
        for a in (shape_a, trans_a):
            if a is not None and a.ndim == 2:
                sizes.append(a.shape[0])
        batched = bool(sizes)
        B = max(sizes) if sizes else 1
        if any(n not in (1, B) for n in sizes):
            raise ValueError(f"smplpix: pose, shape, trans: batch sizes {sizes} differ")

        def norm(a, name, width):
            if a is None:
                return None
            rows = a.shape[0] if (a.ndim == 3 or (a.ndim == 2 and not (a is pose_a and a.shape == (m.nj, 3)))) else 1
            a = np.ascontiguousarray(a.reshape(rows, -1), dtype=dtype)
            if width is not None and a.shape[1] != width:
                raise ValueError(f"smplpix: {name}: expected {width} values per body, got shape {a.shape}")
            if a.shape[0] != B:
                a = np.ascontiguousarray(np.broadcast_to(a, (B, a.shape[1])))
            if not np.all(np.isfinite(a)):
                raise ValueError(f"smplpix: {name}: NaN or Inf")
            return a

        p = norm(pose_a, "pose", m.nj * 3)
        s = norm(shape_a, "shape", None)
        if s is not None and s.shape[1] > m.nbetas:
            raise ValueError(f"smplpix: shape: the model has {m.nbetas} shape directions, got {s.shape[1]}")
        t = norm(trans_a, "trans", 3)
        return B, batched, p, s, t

    def forward(self, pose=None, shape=None, trans=None, *, v_base=None) -> Tuple[np.ndarray, np.ndarray]:
        """spx_body_forward on the open device (float32): pose (K, 3) / (K*3,) axis-angle radians
        or (B, K*3) / (B, K, 3); shape: (S',) or (B, S') betas (the first S' directions); trans (3,)
        or (B, 3); v_base: (N, 3) personal template replacing v_template. None = rest pose / zero
        shape / zero translation. Returns (vertices, joints): (N, 3) and (K, 3), or (B, N, 3),
        (B, K, 3) for batched parameters."""
        m = self.model
        B, batched, p, s, t = self._params(pose, shape, trans, np.float32)
        vb = None if v_base is None else f32(v_base, "v_base", (3,), (2,))
        if vb is not None and vb.shape[0] != m.nv:
            raise ValueError(f"smplpix: v_base: expected ({m.nv}, 3), got {vb.shape}")
        verts = np.empty((B, m.nv, 3), dtype=np.float32)
        joints = np.empty((B, m.nj, 3), dtype=np.float32)
        nb = 0 if s is None else s.shape[1]
        self.ctx.check(L.spx_body_forward(self.ctx.ptr, ctypes.byref(m), B, nb, fptr(s), fptr(p), fptr(t), fptr(vb),
                                          fptr(verts), fptr(joints)))
        return (verts, joints) if batched else (verts[0], joints[0])

    def forward_ref(self, pose=None, shape=None, trans=None) -> Tuple[np.ndarray, np.ndarray]:
        """spx_body_forward_ref: the plain-C double-precision forward of one body (no device);
        returns float64 (N, 3) vertices and (K, 3) joints."""
        m = self.model
        B, batched, p, s, t = self._params(pose, shape, trans, np.float64)
        if B != 1 or batched:
            raise ValueError("smplpix: forward_ref takes the parameters of one body")
        prm = L.spx_body_params(0 if s is None else s.shape[1], dptr(s), dptr(p), dptr(t), None)
        verts = np.empty((m.nv, 3), dtype=np.float64)
        joints = np.empty((m.nj, 3), dtype=np.float64)
        self.ctx.check(L.spx_body_forward_ref(self.ctx.ptr, ctypes.byref(m), ctypes.byref(prm), dptr(verts),
                                              dptr(joints)))
        return verts, joints
