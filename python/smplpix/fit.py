"""Scan-to-body registration (smplpix/fit.h, Ceres behind the library)."""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from . import _lib as L
from ._core import Context, PathLike, _path, carray, dptr, f32, fptr, i32, iptr
from .body import BodyModel
from .io import _c_mesh

_STAGES = {"rigid": 1, "pose": 2, "free": 4}


@dataclass
class Registration:
    """The result of register() (spx_fit_result), as numpy arrays.

    Frames: the scan is first multiplied by unit_scale; x_scan_metres = sim_scale * sim_R @ x_model
    + sim_t. vertices: (N, 3) float32 registration in scan coordinates (input units);
    vertices_model / vertices_pose: float64 (N, 3) final and pose+shape-only in the model frame;
    colors: (N, 3) in [0, 1] transferred from the scan, or None; template_unposed: the personal
    template in the zero-shape rest space (usable as BodyModel.forward(v_base=...)), or None."""
    unit_scale: float
    sim_scale: float
    sim_R: np.ndarray
    sim_t: np.ndarray
    body_scale: float
    betas: np.ndarray
    pose: np.ndarray
    trans: np.ndarray
    vertices: np.ndarray
    vertices_model: Optional[np.ndarray]
    vertices_pose: Optional[np.ndarray]
    colors: Optional[np.ndarray]
    template_unposed: Optional[np.ndarray]
    faces: np.ndarray
    stage_seconds: np.ndarray
    stage_energy: np.ndarray
    stage_mean: np.ndarray
    stages: list


def depth_person(depth, camera, name: str = "depth image"):
    """spx_fit_depth_person: the person in a raw depth frame ((H, W) metres, 0 / NaN = no data, seen
    by camera, a smplpix.Camera of the same size): flying pixels, the floor and walls, what lies
    beyond the person's depth range and other objects are set to 0 in a copy. Returns (depth,
    report) with report a dict of pixel counts (valid, flying, nplanes, planes, range, other,
    kept) and the person's extent (m). No person near the centre is an error (SmplpixError)."""
    d = np.array(f32(depth, "depth", None, (2,)), dtype=np.float32, copy=True)
    c = camera._to_c()
    rep = L.spx_fit_depth_report()
    with Context(device=False) as ctx:
        ctx.check(L.spx_fit_depth_person(ctx.ptr, name.encode(), ctypes.byref(c), fptr(d), d.shape[1], d.shape[0],
                                         ctypes.byref(rep)))
    report = {k: getattr(rep, k) for k in ("valid", "flying", "nplanes", "planes", "range", "other", "kept")}
    report["extent"] = tuple(rep.extent[:])
    return d, report


def depth_points(depth, camera, rgb=None, name: str = "depth image"):
    """spx_fit_depth_points: every pixel with depth back-projected through camera at its centre into
    world coordinates. rgb: (H, W, 3) colours in [0, 1] or None. Returns (points (P, 3) float32,
    colours (P, 3) or None): a scan for register() (seen from camera.eye())."""
    d = f32(depth, "depth", None, (2,))
    col = None if rgb is None else f32(rgb, "rgb", (3,), (3,))
    if col is not None and col.shape[:2] != d.shape:
        raise ValueError(f"smplpix: rgb: shape {col.shape} does not match the depth image {d.shape}")
    c = camera._to_c()
    m = L.spx_mesh()
    with Context(device=False) as ctx:
        ctx.check(L.spx_fit_depth_points(ctx.ptr, name.encode(), ctypes.byref(c), fptr(d), d.shape[1], d.shape[0],
                                         fptr(col), ctypes.byref(m)))
        try:
            pts = carray(m.pos, m.nv * 3, np.float32).reshape(m.nv, 3)
            cols = carray(m.col, m.nv * 3, np.float32)
            return pts, None if cols is None else cols.reshape(m.nv, 3)
        finally:
            L.spx_mesh_free(ctypes.byref(m))


def register(ctx: Context, body: BodyModel, scan_points, scan_colors=None, scan_faces=None, *,
             stages=("rigid", "pose", "free"), progress: Optional[Callable[[dict], None]] = None,
             params_json: Optional[PathLike] = None, view_eyes=None, point_view=None,
             **options) -> Registration:
    """spx_fit_register: register `body` to a scan (mesh or point cloud; >= 10 finite points).

    scan_points (P, 3) float32 in metres, centimetres or millimetres (detected unless
    unit_scale= is given), scan_colors (P, 3) in [0, 1] or None, scan_faces (F, 3) or None.
    stages: a subset of ("rigid", "pose", "free") (rigid always runs; free implies pose).
    options: any field of spx_fit_options (threads, nbetas, unit_scale, max_points_rigid,
    max_points_pose, max_points_free, pose_steps, free_steps, inner_iterations,
    free_inner_iterations, w_shape, w_pose, w_limits, w_scale, w_pose_start, w_m2s, w_lap,
    w_couple_start, w_couple_end, robust_m, seed, ceres_progress); defaults from spx_fit_options_default.
    progress: called with a dict (stage, step, nsteps, energy, mean_dist, seconds, note) after
    every outer step. params_json: also write spx_fit_save_json's parameter file there.
    view_eyes: the centres (K, 3) of the K cameras that saw the scan (e.g. the depth images of
    depth_points, concatenated), point_view (P,) the camera of each point (needed when K > 1):
    what no camera could see is then no evidence."""
    o = L.spx_fit_options()
    L.spx_fit_options_default(ctypes.byref(o))
    mask = 0
    for s in ([stages] if isinstance(stages, str) else stages):
        if s not in _STAGES:
            raise ValueError(f"smplpix: stages: expected rigid, pose or free, got {s!r}")
        mask |= _STAGES[s]
    o.stages = mask
    names = {f[0] for f in L.spx_fit_options._fields_} - {"stages", "progress", "progress_user", "nviews",
                                                           "view_eyes", "point_view"}
    for k, v in options.items():
        if k not in names:
            raise TypeError(f"smplpix: register: unknown option {k!r} (expected one of {sorted(names)})")
        setattr(o, k, v)
    errors = []
    if progress is not None:
        def cb(_user, p):
            if errors:
                return
            try:
                q = p.contents
                progress({"stage": q.stage.decode(), "step": q.step, "nsteps": q.nsteps, "energy": q.energy,
                          "mean_dist": q.mean_dist, "seconds": q.seconds,
                          "note": q.note.decode() if q.note else None})
            except BaseException as e:  # never unwind through C; re-raised after the call
                errors.append(e)
        o.progress = L.spx_fit_progress_fn(cb)
    mesh, keep = _c_mesh(scan_points, scan_faces, scan_colors)
    views = None
    if view_eyes is not None:
        eyes = np.ascontiguousarray(np.asarray(view_eyes, dtype=np.float64).reshape(-1, 3))
        pv = None if point_view is None else i32(point_view, "point_view", None, (1,))
        if pv is not None and pv.shape[0] != mesh.nv:
            raise ValueError(f"smplpix: point_view: {pv.shape[0]} entries for {mesh.nv} scan points")
        o.nviews, o.view_eyes, o.point_view = eyes.shape[0], dptr(eyes), iptr(pv)
        views = (eyes, pv)
    r = L.spx_fit_result()
    ctx.check(L.spx_fit_register(ctx.ptr, ctypes.byref(body.model), ctypes.byref(mesh), ctypes.byref(o),
                                 ctypes.byref(r)))
    try:
        if errors:
            raise errors[0]
        if params_json is not None:
            ctx.check(L.spx_fit_save_json(ctx.ptr, _path(params_json), ctypes.byref(r), None))
        nv = r.nv

        def v3(p, dt):
            a = carray(p, nv * 3, dt)
            return None if a is None else a.reshape(nv, 3)
        return Registration(
            r.unit_scale, r.sim_scale, np.array(r.sim_R[:]).reshape(3, 3), np.array(r.sim_t[:]), r.body_scale,
            carray(r.betas, r.nbetas, np.float64), carray(r.pose, r.nj * 3, np.float64).reshape(r.nj, 3),
            np.array(r.trans[:]), v3(r.verts_scan, np.float32), v3(r.verts_model, np.float64),
            v3(r.verts_pose, np.float64), v3(r.colors, np.float32), v3(r.template_unposed, np.float64),
            carray(r.faces, r.nf * 3, np.int32).reshape(r.nf, 3), np.array(r.stage_seconds[:]),
            np.array(r.stage_energy[:]), np.array(r.stage_mean[:]),
            [s for s, b in _STAGES.items() if r.stages_done & b])
    finally:
        L.spx_fit_result_free(ctypes.byref(r))
        del keep, views
