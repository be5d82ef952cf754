"""The context (smplpix/core.h, smplpix/device.h) and the error type."""
from __future__ import annotations

import ctypes
import os
import weakref
from typing import Optional, Union

import numpy as np

from . import _lib as L

PathLike = Union[str, "os.PathLike[str]"]


class SmplpixError(RuntimeError):
    """A call into libsmplpix failed. ``str(e)`` is the library's one-line message
    (spx_ctx_message: which file, which key or line, what was expected); ``e.status`` the
    spx_status value and ``e.code`` its name ("SPX_E_FORMAT")."""

    def __init__(self, status: int, message: str):
        self.status = int(status)
        self.code = L.spx_status_name(self.status).decode()
        super().__init__(message or self.code)


def _path(p: PathLike) -> bytes:
    """p as the bytes the C library gets; a path with an embedded NUL would be cut short there (and
    name another file), so it is an error, as it cannot reach the CLI either."""
    b = os.fsencode(os.fspath(p))
    if b"\0" in b:
        head = os.fsdecode(b.split(b"\0", 1)[0])
        raise SmplpixError(-1, f"{head}...: the path holds a NUL byte")
    return b


class Context:
    """A libsmplpix context (spx_ctx): carries the last error message and the OpenCL device.

    ``Context(device="cpu" | "gpu" | "P:D" | None)`` creates the context and opens the device
    (None: $SPX_DEVICE, else the first GPU, else the first CPU), as spx_device_open does.
    ``device=False`` opens none (files, cameras and the plain-C reference paths need no device).
    Use it as a context manager or call close(); objects made from it (UNet, BodyModel, ...)
    are closed with it."""

    def __init__(self, device: Union[str, None, bool] = None):
        p = ctypes.c_void_p()
        st = L.spx_ctx_create(ctypes.byref(p))
        if st or not p:
            raise SmplpixError(st or -4, "smplpix: cannot create a context (out of memory)")
        self._ptr = p
        self._children: "weakref.WeakSet" = weakref.WeakSet()
        self._handles: list = [None, None]  # spx_projector, spx_rasterizer
        self._fin = weakref.finalize(self, Context._destroy, p, self._handles)
        if device is not False:
            self.open_device(device)

    # -- lifetime --------------------------------------------------------------------------
    @staticmethod
    def _destroy(p, handles):
        if handles[0]:
            L.spx_projector_destroy(handles[0])
        if handles[1]:
            L.spx_rasterizer_destroy(handles[1])
        L.spx_ctx_destroy(p)

    def close(self) -> None:
        """Free the context, its device and everything made from it (idempotent)."""
        if self._ptr is None:
            return
        for child in list(self._children):
            child.close()
        self._fin.detach()
        Context._destroy(self._ptr, self._handles)
        self._ptr = None
        self._handles[0] = self._handles[1] = None

    def __enter__(self) -> "Context":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def ptr(self) -> ctypes.c_void_p:
        if self._ptr is None:
            raise ValueError("smplpix: the context is closed")
        return self._ptr

    def _adopt(self, child) -> None:
        self._children.add(child)

    def check(self, status: int) -> None:
        """Raise SmplpixError with the context's message when status is negative."""
        if status < 0:
            msg = L.spx_ctx_message(self.ptr).decode(errors="replace")
            L.spx_ctx_clear_error(self.ptr)
            raise SmplpixError(status, msg)

    # -- device ----------------------------------------------------------------------------
    def open_device(self, spec: Optional[str] = None) -> None:
        """spx_device_open: "cpu", "gpu", "P:D" (platform and device indices) or None."""
        if spec is not None and not isinstance(spec, str):
            raise TypeError(f"smplpix: device must be a string like 'cpu', 'gpu' or '0:1', not {spec!r}")
        self.check(L.spx_device_open(self.ptr, spec.encode() if spec else None))

    @property
    def device_open(self) -> bool:
        return bool(L.spx_device_is_open(self.ptr))

    def device_info(self) -> dict:
        """spx_device_get_info as a dict (platform, name, driver, version, kind, ...)."""
        info = L.spx_device_info()
        self.check(L.spx_device_get_info(self.ptr, ctypes.byref(info)))
        return _info_dict(info)

    def finish(self) -> None:
        """spx_device_finish: wait for all queued device work."""
        self.check(L.spx_device_finish(self.ptr))

    def _handle(self, slot, create) -> ctypes.c_void_p:
        """The reusable handle in self._handles[slot], made by create(ctx, &handle) on first use."""
        if self._handles[slot] is None:
            p = ctypes.c_void_p()
            self.check(create(self.ptr, ctypes.byref(p)))
            self._handles[slot] = p
        return self._handles[slot]

    def projector(self) -> ctypes.c_void_p:
        """The context's reusable spx_projector (created on first use)."""
        return self._handle(0, L.spx_projector_create)

    def rasterizer(self) -> ctypes.c_void_p:
        """The context's reusable spx_rasterizer (created on first use)."""
        return self._handle(1, L.spx_rasterizer_create)

    def __repr__(self) -> str:
        if self._ptr is None:
            return "<smplpix.Context closed>"
        if not self.device_open:
            return "<smplpix.Context (no device)>"
        i = self.device_info()
        return f"<smplpix.Context device={i['name']!r} platform={i['platform']!r}>"


def _info_dict(i) -> dict:
    return {"platform": i.platform.decode(errors="replace"), "name": i.name.decode(errors="replace"),
            "driver": i.driver.decode(errors="replace"), "version": i.version.decode(errors="replace"),
            "kind": {1: "cpu", 2: "gpu"}.get(i.kind, "other"), "platform_index": i.platform_index,
            "device_index": i.device_index, "compute_units": i.compute_units, "max_work_group": i.max_work_group,
            "global_mem": i.global_mem, "local_mem": i.local_mem, "max_alloc": i.max_alloc, "fp64": bool(i.fp64)}


def list_devices() -> list:
    """spx_device_list: every OpenCL device on every platform, as dicts."""
    with Context(device=False) as ctx:
        n = ctypes.c_int()
        ctx.check(L.spx_device_list(ctx.ptr, None, 0, ctypes.byref(n)))
        arr = (L.spx_device_info * max(n.value, 1))()
        ctx.check(L.spx_device_list(ctx.ptr, arr, n.value, ctypes.byref(n)))
        return [_info_dict(arr[k]) for k in range(n.value)]


def version() -> str:
    """spx_version: the library's "MAJOR.MINOR.PATCH"."""
    return L.spx_version().decode()


# ---- numpy helpers ---------------------------------------------------------------------------
def f32(a, name: str, shape_tail=None, ndims=None, image: bool = False) -> np.ndarray:
    """a as a C-contiguous float32 array (no copy when it already is one), shape checked. image:
    the CLI's rules for images: every value finite (NaN / Inf is an error naming the element), and
    the one dtype rule of the library (spx_image_npy_values): float as is, uint8 as value/255 like
    an 8-bit PNG, other integer or bool dtypes refused."""
    kind = getattr(getattr(a, "dtype", None), "kind", None)
    if image and kind is not None and kind in "biu":
        if a.dtype != np.uint8:
            raise TypeError(f"smplpix: {name}: {a.dtype} image: integer images must be uint8 (read as value/255, "
                            f"like PNG) or floating point")
        a = np.asarray(a, dtype=np.float32) / np.float32(255)
    try:
        arr = np.ascontiguousarray(a, dtype=np.float32)
    except (TypeError, ValueError) as e:
        raise TypeError(f"smplpix: {name}: expected an array of numbers ({e})") from None
    _check_shape(arr, name, shape_tail, ndims)
    if image and arr.size and not np.isfinite(arr).all():
        bad = int(np.flatnonzero(~np.isfinite(arr.reshape(-1)))[0])
        raise SmplpixError(-9, f"smplpix: {name}: NaN or Inf at element {bad}")
    return arr


def i32(a, name: str, shape_tail=None, ndims=None) -> np.ndarray:
    arr = np.asarray(a)
    if arr.dtype.kind not in "iu" and arr.size:
        raise TypeError(f"smplpix: {name}: expected integers, got {arr.dtype}")
    if arr.size and (arr.min() < -2**31 or arr.max() >= 2**31):
        raise ValueError(f"smplpix: {name}: values do not fit int32")
    arr = np.ascontiguousarray(arr, dtype=np.int32)
    _check_shape(arr, name, shape_tail, ndims)
    return arr


def _check_shape(arr, name, shape_tail, ndims):
    if ndims is not None and arr.ndim not in ndims:
        raise ValueError(f"smplpix: {name}: expected {' or '.join(str(d) for d in ndims)} dimensions, "
                         f"got shape {arr.shape}")
    if shape_tail is not None and arr.shape[arr.ndim - len(shape_tail):] != tuple(shape_tail):
        raise ValueError(f"smplpix: {name}: expected shape (..., {', '.join(map(str, shape_tail))}), "
                         f"got {arr.shape}")


def fptr(a: Optional[np.ndarray]):
    return None if a is None else a.ctypes.data_as(L._F)


def dptr(a: Optional[np.ndarray]):
    return None if a is None else a.ctypes.data_as(L._D)


def iptr(a: Optional[np.ndarray]):
    return None if a is None else a.ctypes.data_as(L._I)


def carray(ptr, count: int, dtype) -> np.ndarray:
    """Copy count elements from a C pointer into a new numpy array (NULL -> None)."""
    if not ptr:
        return None
    return np.ctypeslib.as_array(ptr, shape=(count,)).astype(dtype, copy=True)
