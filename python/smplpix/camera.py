"""Pinhole cameras (smplpix/camera.h; the JSON contract of DESIGN.md).

(u', v', d) = K (R x + t), u = u'/d, v = v'/d; the vertex lands in column floor(u), row floor(v).
K is upper-triangular with K[2][2] == 1 and positive focal lengths, R orthonormal (within 1e-4)
with det > 0, 0 < width, height <= 16384. JSON: {"width", "height", "K", "R", "t"}, one object or
an array of them. Parsing, validation and saving are done by the library."""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import List, Sequence, Union

import numpy as np

from . import _lib as L
from ._core import Context, PathLike, _path


@dataclass
class Camera:
    """One pinhole camera: image size in pixels, K (3x3), R (3x3), t (3), all float64."""
    width: int
    height: int
    K: np.ndarray
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        for name in ("width", "height"):  # whole numbers that reach C unchanged (never wrapped to int32);
            v = getattr(self, name)          # the library's validation judges the size itself
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not -2**31 <= int(v) < 2**31:
                raise ValueError(f"smplpix: camera: {name} needs a whole number (int32), not {v!r}")
        self.width, self.height = int(self.width), int(self.height)
        self.K = np.array(self.K, dtype=np.float64).reshape(3, 3)
        self.R = np.array(self.R, dtype=np.float64).reshape(3, 3)
        self.t = np.array(self.t, dtype=np.float64).reshape(3)

    # -- C struct <-> Camera ---------------------------------------------------------------
    def _to_c(self) -> L.spx_camera:
        c = L.spx_camera()
        c.width, c.height = self.width, self.height
        for r in range(3):
            for k in range(3):
                c.K[r][k] = self.K[r, k]
                c.R[r][k] = self.R[r, k]
            c.t[r] = self.t[r]
        return c

    @staticmethod
    def _from_c(c: L.spx_camera) -> "Camera":
        return Camera(c.width, c.height, [[c.K[r][k] for k in range(3)] for r in range(3)],
                      [[c.R[r][k] for k in range(3)] for r in range(3)], [c.t[r] for r in range(3)])

    def eye(self) -> np.ndarray:
        """The camera's centre in world coordinates, -R^T t."""
        return -self.R.T @ self.t

    def validate(self) -> None:
        """spx_camera_validate: raise SmplpixError naming the problem for an impossible camera."""
        with Context(device=False) as ctx:
            c = self._to_c()
            ctx.check(L.spx_camera_validate(ctx.ptr, b"camera", ctypes.byref(c)))

    # -- JSON ------------------------------------------------------------------------------
    @staticmethod
    def from_json(text: Union[str, bytes], name: str = "camera") -> List["Camera"]:
        """Parse camera JSON (an object or an array) with spx_camera_parse; always a list.
        Errors name `name`, the array index and the key ("cam: [1].R: not orthonormal")."""
        data = text.encode() if isinstance(text, str) else bytes(text)
        with Context(device=False) as ctx:
            cams = ctypes.POINTER(L.spx_camera)()
            n = ctypes.c_int()
            ctx.check(L.spx_camera_parse(ctx.ptr, name.encode(), data, len(data), ctypes.byref(cams), ctypes.byref(n)))
            try:
                return [Camera._from_c(cams[k]) for k in range(n.value)]
            finally:
                _libc_free(cams)

    @staticmethod
    def load(path: PathLike) -> List["Camera"]:
        """spx_camera_load: read a camera JSON file (one object or an array); always a list."""
        with Context(device=False) as ctx:
            cams = ctypes.POINTER(L.spx_camera)()
            n = ctypes.c_int()
            ctx.check(L.spx_camera_load(ctx.ptr, _path(path), ctypes.byref(cams), ctypes.byref(n)))
            try:
                return [Camera._from_c(cams[k]) for k in range(n.value)]
            finally:
                _libc_free(cams)

    @staticmethod
    def save(path: PathLike, cameras: Union["Camera", Sequence["Camera"]]) -> None:
        """spx_camera_save: one camera writes an object, a list writes an array (atomically)."""
        cams = [cameras] if isinstance(cameras, Camera) else list(cameras)
        arr = _c_array(cams)
        with Context(device=False) as ctx:
            ctx.check(L.spx_camera_save(ctx.ptr, _path(path), arr, len(cams)))

    def to_json(self) -> dict:
        """The JSON object of the contract, as a dict (json.dumps it to write it)."""
        return {"width": self.width, "height": self.height, "K": self.K.tolist(), "R": self.R.tolist(),
                "t": self.t.tolist()}

    @staticmethod
    def look_at(width: int, height: int, focal_px: float, eye, target, up=(0.0, 1.0, 0.0)) -> "Camera":
        """spx_camera_look_at: a camera at `eye` looking at `target`, `up` roughly up (OpenCV axes:
        x right, y down, z forward), focal length in pixels, principal point at the centre."""
        e, t, u = (np.ascontiguousarray(v, dtype=np.float64).reshape(3) for v in (eye, target, up))
        c = L.spx_camera()
        with Context(device=False) as ctx:
            ctx.check(L.spx_camera_look_at(ctx.ptr, int(width), int(height), float(focal_px),
                                           e.ctypes.data_as(L._D), t.ctypes.data_as(L._D), u.ctypes.data_as(L._D),
                                           ctypes.byref(c)))
        return Camera._from_c(c)


def _c_array(cams: Sequence[Camera]):
    if not cams:
        raise ValueError("smplpix: cameras: expected at least one camera")
    for c in cams:
        if not isinstance(c, Camera):
            raise TypeError(f"smplpix: cameras: expected smplpix.Camera objects, got {type(c).__name__}")
    arr = (L.spx_camera * len(cams))()
    for k, c in enumerate(cams):
        arr[k] = c._to_c()
    return arr


_libc = ctypes.CDLL(None)
_libc.free.argtypes = [ctypes.c_void_p]
_libc.free.restype = None


def _libc_free(p) -> None:
    """free() for arrays the library malloc'd for the caller (spx_camera_load's *cams)."""
    if p:
        _libc.free(ctypes.cast(p, ctypes.c_void_p))
