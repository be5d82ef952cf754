"""Point projection (smplpix/render.h) and the triangle rasterizer (smplpix/raster.h)."""
from __future__ import annotations

import ctypes
from typing import Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from . import _lib as L
from ._core import Context, f32, fptr, i32, iptr
from .camera import Camera, _c_array

Cameras = Union[Camera, Sequence[Camera]]
_LAYOUTS = {"hwc": 0, "nchw": 1}
_CULL = {"none": 0, "back": 1, "front": 2}
_WRAP = {"repeat": 0, "clamp": 1}


def _cams(cameras: Cameras):
    cams = [cameras] if isinstance(cameras, Camera) else list(cameras)
    arr = _c_array(cams)
    w, h = cams[0].width, cams[0].height
    if any(c.width != w or c.height != h for c in cams):
        raise ValueError("smplpix: cameras: all cameras must have the same width and height")
    return cams, arr, w, h


def _layout(layout: str) -> int:
    if layout not in _LAYOUTS:
        raise ValueError(f"smplpix: layout: expected 'hwc' or 'nchw', got {layout!r}")
    return _LAYOUTS[layout]


class ProjectCall:
    """The arguments of one spx_project call, kept alive with their numpy buffers (used by
    project() and by smplpix.torch for the backward pass)."""

    def __init__(self, vertices, colors, cameras: Cameras, layout: str = "hwc"):
        v = f32(vertices, "vertices", (3,), (2, 3))
        self.squeeze = v.ndim == 2
        self.pos = v.reshape(1, *v.shape) if self.squeeze else v
        self.B, self.N = self.pos.shape[0], self.pos.shape[1]
        if self.B < 1 or self.N < 1:
            raise ValueError(f"smplpix: vertices: expected at least one vertex set of one vertex, got {v.shape}")
        self.col = None
        if colors is not None:
            c = f32(colors, "colors", (3,), (2, 3))
            if c.ndim == 2:
                c = np.ascontiguousarray(np.broadcast_to(c, self.pos.shape)) if self.B > 1 else c.reshape(1, *c.shape)
            if c.shape != self.pos.shape:
                raise ValueError(f"smplpix: colors: shape {c.shape} does not match vertices {self.pos.shape}")
            self.col = c
        self.cams, self.cam_arr, self.W, self.H = _cams(cameras)
        self.C = len(self.cams)
        self.layout = layout
        self.args = L.spx_project_args(self.B, self.N, fptr(self.pos), fptr(self.col), self.C, self.cam_arr,
                                       _layout(layout))

    def image_shape(self) -> Tuple[int, ...]:
        tail = (self.H, self.W, 4) if self.layout == "hwc" else (4, self.H, self.W)
        return (self.B, self.C) + tail

    def shape_out(self, a: np.ndarray) -> np.ndarray:
        return a[0] if self.squeeze else a


def project(ctx: Context, vertices: ArrayLike, colors: Optional[ArrayLike] = None, cameras: Cameras = (), *,
            layout: str = "hwc", return_winners: bool = False,
            reference: bool = False) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """Point projection with collision resolution (SMPLpix eq. 3-4): coloured vertices -> sparse
    RGB-D images (spx_project; spx_project_ref with reference=True).

    vertices: (N, 3) or (B, N, 3) float32; colors: the same shape (any range), (N, 3) shared by
    every set, or None for white; cameras: a Camera or a list (all of the same size).
    Returns (B, C, H, W, 4) float32 (R, G, B, depth), image b*C + c of spx_project (B = 1 for
    (N, 3) input); layout="nchw" gives (B, C, 4, H, W). With return_winners, also the vertex
    index kept at each pixel, int32 (B, C, H, W), -1 for background.

    Contract (DESIGN.md): (u', v', d) = K (R x + t); column floor(u'/d), row floor(v'/d); d <= 0
    and out-of-image points dropped; background (1, 1, 1, 1); nearest depth wins, equal depth ->
    the smallest vertex index; bit-identical on every device and to the reference."""
    call = ProjectCall(vertices, colors, cameras, layout)
    out = np.empty(call.image_shape(), dtype=np.float32)
    win = np.empty((call.B, call.C, call.H, call.W), dtype=np.int32) if return_winners else None
    if reference:
        ctx.check(L.spx_project_ref(ctx.ptr, ctypes.byref(call.args), fptr(out), iptr(win)))
    else:
        ctx.check(L.spx_project(ctx.ptr, ctx.projector(), ctypes.byref(call.args), fptr(out), iptr(win)))
    return (out, win) if return_winners else out


def project_backward(ctx: Context, vertices: ArrayLike, colors: Optional[ArrayLike], cameras: Cameras,
                     winners: ArrayLike, grad_images: ArrayLike, *, layout: str = "hwc",
                     reference: bool = False) -> Tuple[np.ndarray, np.ndarray]:
    """Gradient of a loss through the projection (spx_project_backward; spx_project_backward_ref
    with reference=True). winners and grad_images have the shapes project() returned.
    Returns (grad_colors, grad_vertices), each shaped like vertices. Colours get the image's RGB
    gradient at the pixel each vertex won; positions only through depth (u, v are floored), so
    grad_vertices is the depth gradient times d(depth)/d(x)."""
    call = ProjectCall(vertices, colors, cameras, layout)
    shape = call.image_shape()
    g = f32(grad_images, "grad_images").reshape(shape) if np.size(grad_images) == int(np.prod(shape)) else None
    if g is None:
        raise ValueError(f"smplpix: grad_images: expected {int(np.prod(shape))} values ({shape}), "
                         f"got shape {np.shape(grad_images)}")
    w = i32(winners, "winners")
    if w.size != call.B * call.C * call.H * call.W:
        raise ValueError(f"smplpix: winners: expected {(call.B, call.C, call.H, call.W)}, got {np.shape(winners)}")
    if w.size and (w.min() < -1 or w.max() >= call.N):
        raise ValueError(f"smplpix: winners: indices must be -1 or in [0, {call.N}), got [{w.min()}, {w.max()}]")
    gc = np.zeros(call.pos.shape, dtype=np.float32)
    gp = np.zeros(call.pos.shape, dtype=np.float32)
    if reference:
        L.spx_project_backward_ref(ctypes.byref(call.args), iptr(w), fptr(g), fptr(gc), fptr(gp))
    else:
        ctx.check(L.spx_project_backward(ctx.ptr, ctx.projector(), ctypes.byref(call.args), iptr(w), fptr(g),
                                         fptr(gc), fptr(gp)))
    return call.shape_out(gc), call.shape_out(gp)


def raster(ctx: Context, vertices: ArrayLike, faces: ArrayLike, colors: Optional[ArrayLike] = None,
           cameras: Cameras = (), *, aa: int = 1, cull: str = "none", znear: float = 0.0, layout: str = "hwc",
           uv: Optional[ArrayLike] = None, face_uv: Optional[ArrayLike] = None, texture: Optional[ArrayLike] = None,
           wrap: str = "repeat", return_faces: bool = False,
           reference: bool = False) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """The classic triangle-mesh rasterizer (spx_raster; spx_raster_ref with reference=True):
    the baseline SMPLpix is compared against, with the projection's cameras and output.

    vertices (N, 3) float32, faces (F, 3) int32, colors (N, 3) or None (white); optional texture:
    uv (T, 2), face_uv (F, 3), texture (TH, TW, 3|4) float32 with rows top to bottom (uv (0,0) is
    bottom-left, OBJ convention), wrap "repeat" | "clamp". aa: 1, or 2 = 2x2 supersampling.
    cull: "none", "back", "front" ("front" = counter-clockwise as seen by the camera). znear:
    near plane (0 = SPX_RASTER_ZNEAR = 1e-3). Returns (C, H, W, 4) float32 RGB-D (nearest surface
    wins, perspective-correct colours, depth = camera depth, background (1,1,1,1)); with
    return_faces (aa == 1 only) also the face drawn at each pixel, int32 (C, H, W), -1 background.
    Coverage and winners are identical in the device and reference paths (raster.h)."""
    v = f32(vertices, "vertices", (3,), (2,))
    f = i32(faces, "faces", (3,), (2,))
    if f.size and (f.min() < 0 or f.max() >= v.shape[0]):
        raise ValueError(f"smplpix: faces: vertex indices must be in [0, {v.shape[0]}), got [{f.min()}, {f.max()}]")
    c = None if colors is None else f32(colors, "colors", (3,), (2,))
    if c is not None and c.shape != v.shape:
        raise ValueError(f"smplpix: colors: shape {c.shape} does not match vertices {v.shape}")
    if aa not in (1, 2):
        raise ValueError(f"smplpix: aa: expected 1 or 2, got {aa!r}")
    if cull not in _CULL or wrap not in _WRAP:
        raise ValueError(f"smplpix: cull: expected none/back/front, wrap: repeat/clamp (got {cull!r}, {wrap!r})")
    if return_faces and aa != 1:
        raise ValueError("smplpix: return_faces needs aa=1")
    tex_args = (0, None, None, 0, 0, 0, None)
    if texture is not None or uv is not None or face_uv is not None:
        if texture is None or uv is None or face_uv is None:
            raise ValueError("smplpix: texture needs all of uv, face_uv and texture")
        uv_a = f32(uv, "uv", (2,), (2,))
        fuv = i32(face_uv, "face_uv", (3,), (2,))
        tex = f32(texture, "texture", None, (3,), image=True)
        if tex.shape[2] not in (3, 4):
            raise ValueError(f"smplpix: texture: expected 3 or 4 channels, got shape {tex.shape}")
        if fuv.shape != f.shape or (fuv.size and (fuv.min() < 0 or fuv.max() >= uv_a.shape[0])):
            raise ValueError("smplpix: face_uv: expected (F, 3) indices into uv")
        tex_args = (uv_a.shape[0], fptr(uv_a), iptr(fuv), tex.shape[1], tex.shape[0], tex.shape[2], fptr(tex))
    cams, arr, W, H = _cams(cameras)
    a = L.spx_raster_args(v.shape[0], fptr(v), fptr(c), f.shape[0], iptr(f), *tex_args, _WRAP[wrap], len(cams), arr,
                          aa, _CULL[cull], float(znear), _layout(layout), 0)
    shape = (len(cams), H, W, 4) if layout == "hwc" else (len(cams), 4, H, W)
    out = np.empty(shape, dtype=np.float32)
    fo = np.empty((len(cams), H, W), dtype=np.int32) if return_faces else None
    if reference:
        ctx.check(L.spx_raster_ref(ctx.ptr, ctypes.byref(a), fptr(out), iptr(fo)))
    else:
        ctx.check(L.spx_raster(ctx.ptr, ctx.rasterizer(), ctypes.byref(a), fptr(out), iptr(fo)))
    return (out, fo) if return_faces else out
