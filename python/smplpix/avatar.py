"""A person's own SMPLpix avatar (smplpix/avatar.h), made from their scan by `smplpix avatar`:
the registered body at one vertex count, the colours of those vertices and the network trained
on renders of that person. Posed by the body model's parameters (axis-angle per joint, model
frame in metres, Y up: what BVH / AMASS retargeting gives)."""
from __future__ import annotations

import ctypes
import weakref
from typing import Optional, Tuple

import numpy as np

from . import _lib as L
from ._core import Context, PathLike, _path, carray, dptr, fptr
from .camera import Camera


def _destroy(ctx: Context, handle: list) -> None:  # keeps ctx alive until the avatar is freed
    if handle[0]:
        L.spx_avatar_destroy(handle[0])
        handle[0] = None


class Avatar:
    """spx_avatar: Avatar.load(ctx, "A/avatar.safetensors") (the context's device runs its network);
    freed by close(), with its context, or when collected."""

    def __init__(self, ctx: Context, ptr: ctypes.c_void_p):
        self.ctx = ctx
        self._h = [ptr]
        self._fin = weakref.finalize(self, _destroy, ctx, self._h)
        ctx._adopt(self)

    @classmethod
    def load(cls, ctx: Context, path: PathLike, model: Optional[PathLike] = None) -> "Avatar":
        """spx_avatar_load: the avatar file and the body model it records (or `model`)."""
        p = ctypes.c_void_p()
        ctx.check(L.spx_avatar_load(ctx.ptr, _path(path), None if model is None else _path(model), ctypes.byref(p)))
        return cls(ctx, p)

    @property
    def ptr(self):
        if not self._h[0]:
            raise ValueError("smplpix: the avatar is closed")
        return self._h[0]

    def close(self) -> None:
        self._fin()

    def __enter__(self) -> "Avatar":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _info(self) -> L.spx_avatar_info:
        i = L.spx_avatar_info()
        L.spx_avatar_get_info(self.ptr, ctypes.byref(i))
        return i

    @property
    def info(self) -> dict:
        """vertices, subdivide (Loop steps of the body model), image_size (W, H) it was trained at,
        net_width, joints, train_cpu_seconds, model_path."""
        i = self._info()
        return {"vertices": i.vertices, "subdivide": i.subdivide, "image_size": (i.image_width, i.image_height),
                "net_width": i.net_width, "joints": i.joints, "train_cpu_seconds": i.train_cpu_seconds,
                "model_path": i.model_path.decode() if i.model_path else None}

    @property
    def colors(self) -> np.ndarray:
        """(vertices, 3) float32: the input vertices' colours (a copy)."""
        return carray(L.spx_avatar_colors(self.ptr), self._info().vertices * 3, np.float32).reshape(-1, 3)

    @property
    def faces(self) -> np.ndarray:
        """(F, 3) int32: the faces of the input mesh (a copy)."""
        nf = ctypes.c_int32()
        f = L.spx_avatar_faces(self.ptr, ctypes.byref(nf))
        return carray(f, nf.value * 3, np.int32).reshape(-1, 3)

    @property
    def registration(self) -> dict:
        """The registered pose: betas (S,), pose (joints, 3), trans (3,), body_scale."""
        r = L.spx_avatar_registration(self.ptr).contents
        betas = carray(r.betas, r.nbetas, np.float64) if r.nbetas else np.zeros(0)
        return {"betas": betas, "pose": carray(r.pose, r.nj * 3, np.float64).reshape(-1, 3),
                "trans": np.array(r.trans[:]), "body_scale": r.body_scale}

    def _pose_args(self, pose, trans):
        j = self._info().joints
        p = None if pose is None else np.ascontiguousarray(np.asarray(pose, dtype=np.float64).reshape(-1))
        t = None if trans is None else np.ascontiguousarray(np.asarray(trans, dtype=np.float64).reshape(-1))
        if p is not None and p.size != j * 3:
            raise ValueError(f"smplpix: pose: expected {j} x 3 axis-angle values, got {p.size}")
        if t is not None and t.size != 3:
            raise ValueError(f"smplpix: trans: expected 3 values, got {t.size}")
        return p, t

    def pose_vertices(self, pose=None, trans=None) -> np.ndarray:
        """spx_avatar_pose: the input vertices posed ((vertices, 3) float32, model frame, metres);
        pose (joints, 3) / trans (3,) default to the registered ones."""
        p, t = self._pose_args(pose, trans)
        out = np.empty((self._info().vertices, 3), dtype=np.float32)
        self.ctx.check(L.spx_avatar_pose(self.ptr, dptr(p), dptr(t), fptr(out)))
        return out

    def render(self, camera: Camera, pose=None, trans=None, with_input: bool = False):
        """spx_avatar_render: the avatar posed so through `camera` -> (H, W, 3) float32 (the
        network's output, unclamped); with_input=True also returns the projection it read
        ((H, W, 4), RGB-D)."""
        p, t = self._pose_args(pose, trans)
        c = camera._to_c()
        rgb = np.empty((camera.height, camera.width, 3), dtype=np.float32)
        inp = np.empty((camera.height, camera.width, 4), dtype=np.float32) if with_input else None
        self.ctx.check(L.spx_avatar_render(self.ptr, dptr(p), dptr(t), ctypes.byref(c), fptr(rgb), fptr(inp)))
        return (rgb, inp) if with_input else rgb

    def __repr__(self) -> str:
        i = self._info()
        return f"Avatar({i.vertices} vertices, width {i.net_width}, trained at {i.image_width}x{i.image_height})"
