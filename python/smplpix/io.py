"""Files through the library's readers and writers (smplpix/image.h, npy.h, mesh.h): the same
validation and error messages as the CLI. Images are (H, W, C) float32, rows top to bottom."""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import _lib as L
from ._core import Context, PathLike, _path, f32, fptr, i32, iptr, carray

_DTYPES = {1: np.float32, 2: np.float64, 3: np.uint8, 4: np.int32, 5: np.int64, 6: np.uint32, 7: np.int8,
           8: np.uint64, 9: np.float16, 10: np.bool_}
_CODES = {np.dtype(v): k for k, v in _DTYPES.items()}


def _read_image(fn, path: PathLike) -> np.ndarray:
    img = L.spx_image()
    with Context(device=False) as ctx:
        ctx.check(fn(ctx.ptr, _path(path), ctypes.byref(img)))
        try:
            n = img.height * img.width * img.channels
            return carray(img.data, n, np.float32).reshape(img.height, img.width, img.channels)
        finally:
            L.spx_image_free(ctypes.byref(img))


def _write_image(fn, path: PathLike, image, channels) -> None:
    a = f32(image, "image", None, (2, 3), image=True)
    if a.ndim == 2:
        a = a.reshape(*a.shape, 1)
    if a.shape[2] not in channels:
        raise ValueError(f"smplpix: image: expected {'/'.join(map(str, channels))} channels, got shape {a.shape}")
    img = L.spx_image(a.shape[1], a.shape[0], a.shape[2], fptr(a))
    with Context(device=False) as ctx:
        ctx.check(fn(ctx.ptr, _path(path), ctypes.byref(img)))


def read_exr(path: PathLike) -> np.ndarray:
    """spx_exr_read: an OpenEXR file as (H, W, 4) float32 R, G, B, Z (missing Z reads as 1 =
    background; pixels outside the data window as (1,1,1,1)); a file without R,G,B is an error."""
    return _read_image(L.spx_exr_read, path)


def write_exr(path: PathLike, image) -> None:
    """spx_exr_write: (H, W, 3) -> R,G,B or (H, W, 4) -> R,G,B,Z float32, ZIP, atomically."""
    _write_image(L.spx_exr_write, path, image, (3, 4))


def read_png(path: PathLike) -> np.ndarray:
    """spx_png_read: any PNG as (H, W, 1|3|4) float32 in [0, 1] (palette, 16-bit converted)."""
    return _read_image(L.spx_png_read, path)


def write_png(path: PathLike, image) -> None:
    """spx_png_write: (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) floats in [0, 1] as 8-bit (clamped,
    rounded), atomically. Pass image[..., :3] to write an RGB-D image's colours."""
    _write_image(L.spx_png_write, path, image, (1, 3, 4))


def read_depth(path: PathLike, camera=None) -> np.ndarray:
    """spx_depth_read: a depth image as depth cameras write it, (H, W) float32 metres, 0 = no data.
    16-bit PNG in millimetres; EXR Z (or Y) channel and float NPY in metres; 0, NaN, +inf (and an
    EXR's Z = 1, smplpix's background) are no data. Refused with the library's one-line message:
    negative depth, no depth, one constant depth, the wrong unit (a PNG in metres, an EXR / NPY in
    millimetres, an 8-bit PNG). camera (a smplpix.Camera, optional): the image must be its size and
    its K must fit the image."""
    d = L.spx_depth()
    c = None if camera is None else camera._to_c()
    with Context(device=False) as ctx:
        ctx.check(L.spx_depth_read(ctx.ptr, _path(path), None if c is None else ctypes.byref(c),
                                   b"the camera" if c is not None else None, ctypes.byref(d)))
        try:
            return carray(d.z, d.width * d.height, np.float32).reshape(d.height, d.width)
        finally:
            L.spx_depth_free(ctypes.byref(d))


def read_npy(path: PathLike) -> np.ndarray:
    """spx_npy_load: f4/f8/u1/i4/i8 (and i1/u4/u8/b1/f2) arrays, C order; big-endian files are
    byte-swapped; Fortran order, object arrays and inconsistent shapes are rejected."""
    a = L.spx_array()
    with Context(device=False) as ctx:
        ctx.check(L.spx_npy_load(ctx.ptr, _path(path), ctypes.byref(a)))
        try:
            dt = np.dtype(_DTYPES[a.dtype])
            shape = tuple(a.shape[k] for k in range(a.ndim))
            buf = (ctypes.c_char * a.nbytes).from_address(a.data) if a.nbytes else b""
            return np.frombuffer(bytes(buf), dtype=dt).reshape(shape).copy()
        finally:
            L.spx_array_free(ctypes.byref(a))


def write_npy(path: PathLike, array) -> None:
    """spx_npy_save: write an array (float32/64, (u)int8/32/64, float16, bool) atomically."""
    arr = np.ascontiguousarray(array)
    if arr.dtype not in _CODES:
        raise TypeError(f"smplpix: write_npy: unsupported dtype {arr.dtype}")
    if arr.ndim > L.SPX_NPY_MAX_DIMS:
        raise ValueError(f"smplpix: write_npy: at most {L.SPX_NPY_MAX_DIMS} dimensions, got {arr.ndim}")
    a = L.spx_array()
    a.dtype, a.ndim = _CODES[arr.dtype], arr.ndim
    for k, s in enumerate(arr.shape):
        a.shape[k] = s
    a.data, a.nbytes = arr.ctypes.data, arr.nbytes
    with Context(device=False) as ctx:
        ctx.check(L.spx_npy_save(ctx.ptr, _path(path), ctypes.byref(a)))


@dataclass
class Mesh:
    """A triangle mesh or point cloud (faces of shape (0, 3)): float32 (N, 3) positions,
    optional colours in [0, 1] and normals, int32 (F, 3) faces, optional uv (T, 2) + face_uv."""
    vertices: np.ndarray
    faces: np.ndarray
    colors: Optional[np.ndarray] = None
    normals: Optional[np.ndarray] = None
    uv: Optional[np.ndarray] = None
    face_uv: Optional[np.ndarray] = None


def read_mesh(path: PathLike) -> Mesh:
    """spx_mesh_load: OBJ or PLY (ascii / binary little endian) by extension; 0-255 colours
    are scaled to [0, 1]; polygons fan-triangulated. Errors name the file and line."""
    m = L.spx_mesh()
    with Context(device=False) as ctx:
        ctx.check(L.spx_mesh_load(ctx.ptr, _path(path), ctypes.byref(m)))
        try:
            def v3(p, n):
                a = carray(p, n * 3, np.float32)
                return None if a is None else a.reshape(n, 3)
            faces = carray(m.faces, m.nf * 3, np.int32)
            uv = carray(m.uv, m.nuv * 2, np.float32)
            fuv = carray(m.face_uv, m.nf * 3, np.int32)
            return Mesh(v3(m.pos, m.nv), np.zeros((0, 3), np.int32) if faces is None else faces.reshape(m.nf, 3),
                        v3(m.col, m.nv), v3(m.nrm, m.nv), None if uv is None else uv.reshape(m.nuv, 2),
                        None if fuv is None else fuv.reshape(m.nf, 3))
        finally:
            L.spx_mesh_free(ctypes.byref(m))


def _c_mesh(vertices, faces=None, colors=None, normals=None):
    """An spx_mesh viewing numpy arrays (kept alive in the returned tuple)."""
    v = f32(vertices, "vertices", (3,), (2,))
    f = i32(np.zeros((0, 3), np.int32) if faces is None else faces, "faces", (3,), (2,))
    c = None if colors is None else f32(colors, "colors", (3,), (2,))
    n = None if normals is None else f32(normals, "normals", (3,), (2,))
    for name, a in (("colors", c), ("normals", n)):
        if a is not None and a.shape != v.shape:
            raise ValueError(f"smplpix: {name}: shape {a.shape} does not match vertices {v.shape}")
    m = L.spx_mesh(v.shape[0], f.shape[0], fptr(v), fptr(c), fptr(n), iptr(f) if f.size else None, 0, None, None)
    return m, (v, f, c, n)


def write_mesh(path: PathLike, mesh: Mesh, fmt: str = "auto") -> None:
    """spx_mesh_save: fmt "auto" (by extension; PLY -> binary), "obj", "ply", "ply-ascii";
    written atomically. (Texture coordinates are not written by this binding.)"""
    fmts = {"auto": 0, "obj": 1, "ply-ascii": 2, "ply": 3}
    if fmt not in fmts:
        raise ValueError(f"smplpix: fmt: expected one of {sorted(fmts)}, got {fmt!r}")
    m, keep = _c_mesh(mesh.vertices, mesh.faces, mesh.colors, mesh.normals)
    with Context(device=False) as ctx:
        ctx.check(L.spx_mesh_save(ctx.ptr, _path(path), ctypes.byref(m), fmts[fmt]))
    del keep
