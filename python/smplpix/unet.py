"""The SMPLpix UNet (smplpix/unet.h): RGB-D in, RGB out, PyTorch "milesial" checkpoint names."""
from __future__ import annotations

import ctypes
import weakref
from typing import Dict

import numpy as np

from . import _lib as L
from ._core import Context, PathLike, _path, f32, fptr


def _destroy(ctx: Context, handle: list) -> None:  # keeps ctx alive until the net is freed
    if handle[0]:
        L.spx_unet_destroy(handle[0])
        handle[0] = None


class UNet:
    """A UNet on the context's device (spx_unet). Make one with UNet.load(ctx, path) or
    UNet.create(ctx, width, ...); it is freed by close(), with its context, or when collected."""

    def __init__(self, ctx: Context, ptr: ctypes.c_void_p):
        self.ctx = ctx
        self._h = [ptr]
        self._fin = weakref.finalize(self, _destroy, ctx, self._h)
        ctx._adopt(self)

    @property
    def ptr(self):
        if not self._h[0]:
            raise ValueError("smplpix: the UNet is closed")
        return self._h[0]

    def close(self) -> None:
        self._fin()

    def __enter__(self) -> "UNet":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @classmethod
    def load(cls, ctx: Context, path: PathLike) -> "UNet":
        """spx_unet_load: a safetensors checkpoint (base width read from
        inc.double_conv.0.weight; F32 or F16 weights; unknown tensors ignored; the optimizer state
        restored when present; sigmoid from the metadata key "smplpix.sigmoid")."""
        p = ctypes.c_void_p()
        ctx.check(L.spx_unet_load(ctx.ptr, _path(path), ctypes.byref(p)))
        return cls(ctx, p)

    @classmethod
    def create(cls, ctx: Context, width: int = 64, sigmoid: bool = False, seed: int = 0) -> "UNet":
        """spx_unet_create: a new network of base width 8, 16, 32 or 64 (64 = the paper) with
        PyTorch's default initialisation drawn from `seed`."""
        if not 0 <= int(seed) < 2**64:
            raise ValueError(f"smplpix: seed: expected 0 <= seed < 2**64, got {seed}")
        p = ctypes.c_void_p()
        ctx.check(L.spx_unet_create(ctx.ptr, int(width), int(bool(sigmoid)), int(seed), ctypes.byref(p)))
        return cls(ctx, p)

    def save(self, path: PathLike, with_optimizer: bool = False) -> None:
        """spx_unet_save: state_dict names (+ the Adam state when with_optimizer), written to a
        temporary file renamed over path."""
        self.ctx.check(L.spx_unet_save(self.ptr, _path(path), int(bool(with_optimizer))))

    @property
    def width(self) -> int:
        return L.spx_unet_width(self.ptr)

    @property
    def sigmoid(self) -> bool:
        return bool(L.spx_unet_sigmoid(self.ptr))

    @sigmoid.setter
    def sigmoid(self, on: bool) -> None:
        L.spx_unet_set_sigmoid(self.ptr, int(bool(on)))

    def render(self, rgbd) -> np.ndarray:
        """Inference forward (spx_unet_forward, train = 0: batch norm folded, running statistics).
        rgbd: (N, 4, H, W) float32 NCHW -> (N, 3, H, W); or one (H, W, 4) HWC image (what
        project() and read_exr() return) -> (H, W, 3). H, W >= 16."""
        x = f32(rgbd, "rgbd", None, (3, 4), image=True)
        hwc = x.ndim == 3
        if hwc:
            if x.shape[2] != 4:
                raise ValueError(f"smplpix: rgbd: expected (H, W, 4) or (N, 4, H, W), got {x.shape}")
            x = np.ascontiguousarray(x.transpose(2, 0, 1)[None])
        if x.shape[1] != 4:
            raise ValueError(f"smplpix: rgbd: expected (N, 4, H, W) or (H, W, 4), got {x.shape}")
        n, _, h, w = x.shape
        out = np.empty((n, 3, h, w), dtype=np.float32)
        self.ctx.check(L.spx_unet_forward(self.ptr, fptr(x), n, h, w, 0, fptr(out)))
        return np.ascontiguousarray(out[0].transpose(1, 2, 0)) if hwc else out

    def render_points(self, vertices, colors=None, cameras=()) -> np.ndarray:
        """Project and render without leaving the device: spx_project_to_tensor writes the
        RGB-D images into a device tensor (smplpix/device.h) that spx_unet_forward_tensor reads
        (what `smplpix render --mesh` runs). Arguments as project(); returns (B, C, 3, H, W)
        float32, equal bit for bit to render(project(..., layout="nchw")) on the same images."""
        from .render import ProjectCall
        call = ProjectCall(vertices, colors, cameras, "nchw")
        n = call.B * call.C
        t = ctypes.c_void_p()
        self.ctx.check(L.spx_device_tensor_create(self.ctx.ptr, n, 4, call.H, call.W, ctypes.byref(t)))
        try:
            out = np.empty((call.B, call.C, 3, call.H, call.W), dtype=np.float32)
            self.ctx.check(L.spx_project_to_tensor(self.ctx.ptr, self.ctx.projector(), ctypes.byref(call.args), t))
            self.ctx.check(L.spx_unet_forward_tensor(self.ptr, t, fptr(out)))
            return out
        finally:
            L.spx_device_tensor_free(t)

    def state_dict(self) -> Dict[str, np.ndarray]:
        """Every tensor by its state_dict name (spx_unet_tensor_name / spx_unet_read), float32."""
        out = {}
        for i in range(L.spx_unet_tensor_count(self.ptr)):
            nd = ctypes.c_int()
            shape = (ctypes.c_int64 * 4)()
            name = L.spx_unet_tensor_name(self.ptr, i, ctypes.byref(nd), shape)
            dims = tuple(shape[k] for k in range(nd.value))
            a = np.empty(dims, dtype=np.float32)
            self.ctx.check(L.spx_unet_read(self.ptr, name, 0, fptr(a), a.size))
            out[name.decode()] = a
        return out
