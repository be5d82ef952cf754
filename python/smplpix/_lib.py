"""Loading libsmplpix and declaring the C API (ctypes; mirrors lib/include/smplpix/*.h).

Only the public headers are used. Every struct here has the layout of its C declaration; keep
them in step when a header changes: a field added to a struct (spx_fit_options, spx_raster_args,
spx_body_model, spx_fit_result, spx_camera, spx_device_info, ...) goes here in the same place, or
the binding reads garbage (python/tests compares every binding with the CLI and catches most shifts).

The rules of the package: shapes and dtypes are checked in Python (ValueError / TypeError) before
any call; every status goes through Context.check, which raises SmplpixError with the context's
message; an object owning a library handle frees it with weakref.finalize holding its Context
among the finalizer's arguments, so a context never goes before its UNets and body models; a
Python exception in a progress callback never unwinds through C: it is kept and raised again
after the call."""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import subprocess
from ctypes import (CFUNCTYPE, POINTER, Structure, c_char, c_char_p, c_double, c_float, c_int, c_int32,
                    c_int64, c_size_t, c_uint, c_uint32, c_uint64, c_void_p)

_HERE = os.path.dirname(os.path.abspath(__file__))


def _candidates():
    env = os.environ.get("SMPLPIX_LIBRARY")
    if env:  # an explicit file (e.g. the CMake build tree's build/libsmplpix.so)
        yield env
        return
    # 1. shipped inside the wheel (pip install ./python puts the CMake install under smplpix/)
    for sub in ("lib", "lib64"):
        d = os.path.join(_HERE, sub)
        if os.path.isdir(d):
            for name in sorted(os.listdir(d)):
                if name.startswith("libsmplpix.so"):
                    yield os.path.join(d, name)
    # 2. an installed libsmplpix found through pkg-config (make install PREFIX=...)
    #    (libdir as configured, and the folder above the .pc file, which is right even when the
    #    install prefix was chosen at install time: cmake --install --prefix)
    for var, sub in (("libdir", "."), ("pcfiledir", "..")):
        try:
            d = subprocess.run(["pkg-config", f"--variable={var}", "smplpix"], capture_output=True, text=True,
                               check=False, timeout=10).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            continue
        if d:
            yield os.path.normpath(os.path.join(d, sub, "libsmplpix.so.0"))
    # 3. the dynamic linker's search path
    found = ctypes.util.find_library("smplpix")
    if found:
        yield found


def _load():
    tried = []
    for path in _candidates():
        try:
            return ctypes.CDLL(path), path
        except OSError as e:
            tried.append(f"{path} ({e})")
    raise ImportError("smplpix: cannot find libsmplpix; install the package with `pip install ./python`, "
                      "install the library (make install) so that pkg-config finds it, or set SMPLPIX_LIBRARY "
                      "to the .so file" + ("; tried: " + "; ".join(tried) if tried else ""))


lib, LIBRARY_PATH = _load()

# ---- structs (smplpix/*.h) -------------------------------------------------------------------


class spx_camera(Structure):
    _fields_ = [("width", c_int32), ("height", c_int32), ("K", (c_double * 3) * 3), ("R", (c_double * 3) * 3),
                ("t", c_double * 3)]


class spx_device_info(Structure):
    _fields_ = [("platform", c_char * 256), ("name", c_char * 256), ("driver", c_char * 128),
                ("version", c_char * 128), ("kind", c_int), ("platform_index", c_int), ("device_index", c_int),
                ("compute_units", c_uint), ("max_work_group", c_size_t), ("global_mem", c_uint64),
                ("local_mem", c_uint64), ("max_alloc", c_uint64), ("fp64", c_int)]


class spx_project_args(Structure):
    _fields_ = [("batch", c_int32), ("nverts", c_int32), ("pos", POINTER(c_float)), ("col", POINTER(c_float)),
                ("ncams", c_int32), ("cams", POINTER(spx_camera)), ("layout", c_int)]


class spx_raster_args(Structure):
    _fields_ = [("nverts", c_int32), ("pos", POINTER(c_float)), ("col", POINTER(c_float)), ("nfaces", c_int32),
                ("faces", POINTER(c_int32)), ("nuv", c_int32), ("uv", POINTER(c_float)),
                ("face_uv", POINTER(c_int32)), ("tex_width", c_int32), ("tex_height", c_int32),
                ("tex_channels", c_int32), ("tex", POINTER(c_float)), ("wrap", c_int), ("ncams", c_int32),
                ("cams", POINTER(spx_camera)), ("aa", c_int32), ("cull", c_int), ("znear", c_float),
                ("layout", c_int), ("static_id", c_uint32)]


class spx_image(Structure):
    _fields_ = [("width", c_int32), ("height", c_int32), ("channels", c_int32), ("data", POINTER(c_float))]


SPX_NPY_MAX_DIMS = 8


class spx_array(Structure):
    _fields_ = [("dtype", c_int), ("ndim", c_int), ("shape", c_int64 * SPX_NPY_MAX_DIMS), ("data", c_void_p),
                ("nbytes", c_size_t)]


class spx_mesh(Structure):
    _fields_ = [("nv", c_int32), ("nf", c_int32), ("pos", POINTER(c_float)), ("col", POINTER(c_float)),
                ("nrm", POINTER(c_float)), ("faces", POINTER(c_int32)), ("nuv", c_int32), ("uv", POINTER(c_float)),
                ("face_uv", POINTER(c_int32))]


class spx_body_model(Structure):
    _fields_ = [("nv", c_int32), ("nj", c_int32), ("nbetas", c_int32), ("nposedirs", c_int32), ("nf", c_int32),
                ("v_template", POINTER(c_float)), ("shapedirs", POINTER(c_float)), ("posedirs", POINTER(c_float)),
                ("J_regressor", POINTER(c_float)), ("weights", POINTER(c_float)), ("parents", POINTER(c_int32)),
                ("faces", POINTER(c_int32)), ("joint_names", POINTER(c_char_p)), ("nvt", c_int32),
                ("vt", POINTER(c_float)), ("ft", POINTER(c_int32)), ("J_template", POINTER(c_double)),
                ("J_shapedirs", POINTER(c_double)), ("dev", c_void_p)]


class spx_body_params(Structure):
    _fields_ = [("nbetas", c_int32), ("betas", POINTER(c_double)), ("pose", POINTER(c_double)),
                ("trans", POINTER(c_double)), ("v_base", POINTER(c_double))]


class spx_fit_progress(Structure):
    _fields_ = [("stage", c_char_p), ("step", c_int32), ("nsteps", c_int32), ("energy", c_double),
                ("mean_dist", c_double), ("seconds", c_double), ("note", c_char_p)]


spx_fit_progress_fn = CFUNCTYPE(None, c_void_p, POINTER(spx_fit_progress))


class spx_fit_options(Structure):
    _fields_ = [("stages", c_int), ("threads", c_int), ("nbetas", c_int), ("unit_scale", c_double),
                ("max_points_rigid", c_int32), ("max_points_pose", c_int32), ("max_points_free", c_int32),
                ("pose_steps", c_int32), ("free_steps", c_int32), ("inner_iterations", c_int32),
                ("free_inner_iterations", c_int32), ("w_shape", c_double), ("w_pose", c_double),
                ("w_limits", c_double), ("w_scale", c_double), ("w_pose_start", c_double), ("w_m2s", c_double),
                ("w_lap", c_double), ("w_couple_start", c_double), ("w_couple_end", c_double),
                ("robust_m", c_double), ("seed", c_uint64), ("progress", spx_fit_progress_fn),
                ("progress_user", c_void_p), ("ceres_progress", c_int), ("view", c_int),
                ("view_eye", c_double * 3), ("aids", c_uint), ("nviews", c_int32), ("view_eyes", POINTER(c_double)),
                ("point_view", POINTER(c_int32))]


class spx_depth(Structure):
    _fields_ = [("width", c_int32), ("height", c_int32), ("z", POINTER(c_float)), ("nvalid", c_int64)]


class spx_fit_depth_report(Structure):
    _fields_ = [("valid", c_int64), ("flying", c_int64), ("nplanes", c_int), ("planes", c_int64), ("range", c_int64),
                ("other", c_int64), ("kept", c_int64), ("extent", c_double * 3)]


class spx_fit_result(Structure):
    _fields_ = [("nv", c_int32), ("nj", c_int32), ("nbetas", c_int32), ("nf", c_int32), ("unit_scale", c_double),
                ("sim_scale", c_double), ("sim_R", c_double * 9), ("sim_t", c_double * 3), ("body_scale", c_double),
                ("betas", POINTER(c_double)), ("pose", POINTER(c_double)), ("trans", c_double * 3),
                ("verts_model", POINTER(c_double)), ("verts_pose", POINTER(c_double)),
                ("verts_scan", POINTER(c_float)), ("colors", POINTER(c_float)),
                ("template_unposed", POINTER(c_double)), ("faces", POINTER(c_int32)),
                ("stage_seconds", c_double * 3), ("stage_energy", c_double * 3), ("stage_mean", c_double * 3),
                ("stages_done", c_int)]


class spx_avatar_info(Structure):
    _fields_ = [("vertices", c_int32), ("subdivide", c_int32), ("image_width", c_int32), ("image_height", c_int32),
                ("net_width", c_int32), ("joints", c_int32), ("train_cpu_seconds", c_double),
                ("model_path", c_char_p)]


# ---- functions -------------------------------------------------------------------------------
_ctx_p = c_void_p
_st = c_int
_F = POINTER(c_float)
_D = POINTER(c_double)
_I = POINTER(c_int32)


def _fn(name, restype, *argtypes):
    f = getattr(lib, name)
    f.restype = restype
    f.argtypes = list(argtypes)
    return f


spx_status_name = _fn("spx_status_name", c_char_p, c_int)
spx_version = _fn("spx_version", c_char_p)
spx_ctx_create = _fn("spx_ctx_create", _st, POINTER(c_void_p))
spx_ctx_destroy = _fn("spx_ctx_destroy", None, _ctx_p)
spx_ctx_message = _fn("spx_ctx_message", c_char_p, _ctx_p)
spx_ctx_last_status = _fn("spx_ctx_last_status", c_int, _ctx_p)
spx_ctx_clear_error = _fn("spx_ctx_clear_error", None, _ctx_p)

spx_device_open = _fn("spx_device_open", _st, _ctx_p, c_char_p)
spx_device_is_open = _fn("spx_device_is_open", c_int, _ctx_p)
spx_device_get_info = _fn("spx_device_get_info", _st, _ctx_p, POINTER(spx_device_info))
spx_device_finish = _fn("spx_device_finish", _st, _ctx_p)
spx_device_list = _fn("spx_device_list", _st, _ctx_p, POINTER(spx_device_info), c_int, POINTER(c_int))

spx_camera_parse = _fn("spx_camera_parse", _st, _ctx_p, c_char_p, c_char_p, c_size_t, POINTER(POINTER(spx_camera)),
                       POINTER(c_int))
spx_camera_load = _fn("spx_camera_load", _st, _ctx_p, c_char_p, POINTER(POINTER(spx_camera)), POINTER(c_int))
spx_camera_validate = _fn("spx_camera_validate", _st, _ctx_p, c_char_p, POINTER(spx_camera))
spx_camera_save = _fn("spx_camera_save", _st, _ctx_p, c_char_p, POINTER(spx_camera), c_int)
spx_camera_look_at = _fn("spx_camera_look_at", _st, _ctx_p, c_int32, c_int32, c_double, _D, _D, _D,
                         POINTER(spx_camera))

spx_projector_create = _fn("spx_projector_create", _st, _ctx_p, POINTER(c_void_p))
spx_projector_destroy = _fn("spx_projector_destroy", None, c_void_p)
spx_project = _fn("spx_project", _st, _ctx_p, c_void_p, POINTER(spx_project_args), _F, _I)
spx_project_backward = _fn("spx_project_backward", _st, _ctx_p, c_void_p, POINTER(spx_project_args), _I, _F, _F, _F)
spx_project_ref = _fn("spx_project_ref", _st, _ctx_p, POINTER(spx_project_args), _F, _I)
spx_project_backward_ref = _fn("spx_project_backward_ref", None, POINTER(spx_project_args), _I, _F, _F, _F)

spx_rasterizer_create = _fn("spx_rasterizer_create", _st, _ctx_p, POINTER(c_void_p))
spx_rasterizer_destroy = _fn("spx_rasterizer_destroy", None, c_void_p)
spx_raster = _fn("spx_raster", _st, _ctx_p, c_void_p, POINTER(spx_raster_args), _F, _I)
spx_raster_ref = _fn("spx_raster_ref", _st, _ctx_p, POINTER(spx_raster_args), _F, _I)

spx_image_free = _fn("spx_image_free", None, POINTER(spx_image))
spx_exr_write = _fn("spx_exr_write", _st, _ctx_p, c_char_p, POINTER(spx_image))
spx_exr_read = _fn("spx_exr_read", _st, _ctx_p, c_char_p, POINTER(spx_image))
spx_png_write = _fn("spx_png_write", _st, _ctx_p, c_char_p, POINTER(spx_image))
spx_png_read = _fn("spx_png_read", _st, _ctx_p, c_char_p, POINTER(spx_image))
spx_npy_load = _fn("spx_npy_load", _st, _ctx_p, c_char_p, POINTER(spx_array))
spx_npy_save = _fn("spx_npy_save", _st, _ctx_p, c_char_p, POINTER(spx_array))
spx_array_free = _fn("spx_array_free", None, POINTER(spx_array))
spx_mesh_load = _fn("spx_mesh_load", _st, _ctx_p, c_char_p, POINTER(spx_mesh))
spx_mesh_save = _fn("spx_mesh_save", _st, _ctx_p, c_char_p, POINTER(spx_mesh), c_int)
spx_mesh_free = _fn("spx_mesh_free", None, POINTER(spx_mesh))

spx_unet_create = _fn("spx_unet_create", _st, _ctx_p, c_int, c_int, c_uint64, POINTER(c_void_p))
spx_unet_destroy = _fn("spx_unet_destroy", None, c_void_p)
spx_unet_width = _fn("spx_unet_width", c_int, c_void_p)
spx_unet_sigmoid = _fn("spx_unet_sigmoid", c_int, c_void_p)
spx_unet_set_sigmoid = _fn("spx_unet_set_sigmoid", None, c_void_p, c_int)
spx_unet_forward = _fn("spx_unet_forward", _st, c_void_p, _F, c_int, c_int, c_int, c_int, _F)
spx_unet_save = _fn("spx_unet_save", _st, c_void_p, c_char_p, c_int)
spx_unet_load = _fn("spx_unet_load", _st, _ctx_p, c_char_p, POINTER(c_void_p))
spx_unet_tensor_count = _fn("spx_unet_tensor_count", c_int, c_void_p)
spx_unet_tensor_name = _fn("spx_unet_tensor_name", c_char_p, c_void_p, c_int, POINTER(c_int), c_int64 * 4)
spx_unet_read = _fn("spx_unet_read", _st, c_void_p, c_char_p, c_int, _F, c_size_t)

spx_body_load = _fn("spx_body_load", _st, _ctx_p, c_char_p, POINTER(spx_body_model))
spx_body_free = _fn("spx_body_free", None, POINTER(spx_body_model))
spx_body_forward = _fn("spx_body_forward", _st, _ctx_p, POINTER(spx_body_model), c_int32, c_int32, _F, _F, _F, _F,
                       _F, _F)
spx_body_forward_ref = _fn("spx_body_forward_ref", _st, _ctx_p, POINTER(spx_body_model), POINTER(spx_body_params),
                           _D, _D)

spx_depth_read = _fn("spx_depth_read", _st, _ctx_p, c_char_p, POINTER(spx_camera), c_char_p, POINTER(spx_depth))
spx_depth_free = _fn("spx_depth_free", None, POINTER(spx_depth))
spx_fit_depth_person = _fn("spx_fit_depth_person", _st, _ctx_p, c_char_p, POINTER(spx_camera), _F, c_int32, c_int32,
                           POINTER(spx_fit_depth_report))
spx_fit_depth_points = _fn("spx_fit_depth_points", _st, _ctx_p, c_char_p, POINTER(spx_camera), _F, c_int32, c_int32,
                           _F, POINTER(spx_mesh))
spx_fit_options_default = _fn("spx_fit_options_default", None, POINTER(spx_fit_options))
spx_fit_register = _fn("spx_fit_register", _st, _ctx_p, POINTER(spx_body_model), POINTER(spx_mesh),
                       POINTER(spx_fit_options), POINTER(spx_fit_result))
spx_fit_result_free = _fn("spx_fit_result_free", None, POINTER(spx_fit_result))
spx_fit_save_json = _fn("spx_fit_save_json", _st, _ctx_p, c_char_p, POINTER(spx_fit_result), c_char_p)

spx_device_tensor_create = _fn("spx_device_tensor_create", _st, _ctx_p, c_int, c_int, c_int, c_int, POINTER(c_void_p))
spx_device_tensor_free = _fn("spx_device_tensor_free", None, c_void_p)
spx_project_to_tensor = _fn("spx_project_to_tensor", _st, _ctx_p, c_void_p, POINTER(spx_project_args), c_void_p)
spx_unet_forward_tensor = _fn("spx_unet_forward_tensor", _st, c_void_p, c_void_p, _F)

spx_avatar_load = _fn("spx_avatar_load", _st, _ctx_p, c_char_p, c_char_p, POINTER(c_void_p))
spx_avatar_destroy = _fn("spx_avatar_destroy", None, c_void_p)
spx_avatar_get_info = _fn("spx_avatar_get_info", None, c_void_p, POINTER(spx_avatar_info))
spx_avatar_registration = _fn("spx_avatar_registration", POINTER(spx_fit_result), c_void_p)
spx_avatar_colors = _fn("spx_avatar_colors", _F, c_void_p)
spx_avatar_faces = _fn("spx_avatar_faces", _I, c_void_p, _I)
spx_avatar_pose = _fn("spx_avatar_pose", _st, c_void_p, _D, _D, _F)
spx_avatar_render = _fn("spx_avatar_render", _st, c_void_p, _D, _D, POINTER(spx_camera), _F, _F)
