"""smplpix: the SMPLpix neural avatar renderer (C11 + OpenCL) from Python.

A thin ctypes layer over libsmplpix's public headers (lib/include/smplpix/*.h): numpy float32
C-order arrays in and out, errors raised as SmplpixError carrying the library's one-line message.

    import smplpix
    ctx = smplpix.Context(device="cpu")
    mesh = smplpix.read_mesh("data/body/human_woman.obj")
    cam = smplpix.Camera.load("data/cameras/default.json")
    img = smplpix.project(ctx, mesh.vertices, mesh.colors, cam)   # (1, 1, H, W, 4): B, C, H, W, (R, G, B, depth)

`smplpix.torch` (needs PyTorch) makes the projection a torch.autograd.Function."""
from ._core import Context, SmplpixError, list_devices, version
from ._lib import LIBRARY_PATH
from .avatar import Avatar
from .body import BodyModel
from .camera import Camera
from .fit import Registration, depth_person, depth_points, register
from .io import (Mesh, read_depth, read_exr, read_mesh, read_npy, read_png, write_exr, write_mesh, write_npy,
                 write_png)
from .render import project, project_backward, raster
from .unet import UNet

__version__ = "0.1.0"
__all__ = ["Context", "SmplpixError", "list_devices", "version", "LIBRARY_PATH", "Avatar", "BodyModel", "Camera",
           "Registration", "register", "depth_person", "depth_points", "Mesh", "read_depth", "read_exr", "read_mesh",
           "read_npy", "read_png", "write_exr", "write_mesh", "write_npy", "write_png", "project", "project_backward",
           "raster", "UNet"]
