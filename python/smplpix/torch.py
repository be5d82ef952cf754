"""PyTorch autograd for the projection (needs torch; `import smplpix.torch`).

project(ctx, vertices, colors, cameras) is a torch.autograd.Function: the forward is
spx_project (or spx_project_ref), the backward spx_project_backward (spx_project_backward_ref):
gradients reach the colours (the RGB gradient at the pixel each vertex won) and the positions
only through the depth channel (u, v are floored, so the pixel a vertex lands in is piecewise
constant in the position and has no gradient). Computation is float32 in the library; float64
tensors are converted on the way in and the results cast back (gradcheck runs in float64 against
the plain-C reference path, whose arithmetic is exact enough for finite differences)."""
from __future__ import annotations

from typing import Sequence, Union

import numpy as np
import torch as _torch

from . import render as _render
from ._core import Context
from .camera import Camera


class ProjectFunction(_torch.autograd.Function):
    """The projection as an autograd Function; use smplpix.torch.project()."""

    @staticmethod
    def forward(fctx, vertices, colors, ctx, cameras, layout, reference):
        v = vertices.detach().cpu().numpy().astype(np.float32)
        c = None if colors is None else colors.detach().cpu().numpy().astype(np.float32)
        img, win = _render.project(ctx, v, c, cameras, layout=layout, return_winners=True, reference=reference)
        fctx.save_for_backward(vertices, colors if colors is not None else vertices.new_empty(0))
        fctx.has_colors = colors is not None
        fctx.win, fctx.ctx, fctx.cameras, fctx.layout, fctx.reference = win, ctx, cameras, layout, reference
        return _torch.from_numpy(img).to(device=vertices.device, dtype=vertices.dtype)

    @staticmethod
    def backward(fctx, grad_img):
        vertices, colors = fctx.saved_tensors
        v = vertices.detach().cpu().numpy().astype(np.float32)
        c = colors.detach().cpu().numpy().astype(np.float32) if fctx.has_colors else None
        g = grad_img.detach().cpu().numpy().astype(np.float32)
        gc, gp = _render.project_backward(fctx.ctx, v, c, fctx.cameras, fctx.win, g, layout=fctx.layout,
                                          reference=fctx.reference)
        gv = _torch.from_numpy(gp).to(device=vertices.device, dtype=vertices.dtype)
        gcol = _torch.from_numpy(gc).to(device=vertices.device, dtype=vertices.dtype) if fctx.has_colors else None
        return (gv if fctx.needs_input_grad[0] else None, gcol if fctx.needs_input_grad[1] else None,
                None, None, None, None)


def project(ctx: Context, vertices: "_torch.Tensor", colors: "_torch.Tensor" = None,
            cameras: Union[Camera, Sequence[Camera]] = (), *, layout: str = "hwc",
            reference: bool = False) -> "_torch.Tensor":
    """Differentiable projection: vertices (N, 3) / (B, N, 3) and colours (same shape, or None =
    white) as torch tensors -> images (C, H, W, 4) / (B, C, H, W, 4) (layout "nchw": (..., 4, H, W)),
    on the device and dtype of `vertices`. Backward: spx_project_backward (reference=True: the
    plain-C forward and backward). See the module docstring for which gradients exist."""
    if colors is not None and colors.shape != vertices.shape:
        raise ValueError(f"smplpix: colors: shape {tuple(colors.shape)} does not match vertices "
                         f"{tuple(vertices.shape)}")
    return ProjectFunction.apply(vertices, colors, ctx, cameras, layout, reference)
