"""smplpix.torch.project: gradcheck in float64 against the plain-C reference path, the device
path's gradients equal to the reference's, and the PyTorch3D-style semantics docs/python.md states."""
import numpy as np
import pytest

torch = pytest.importorskip("torch")
import smplpix  # noqa: E402
import smplpix.torch as spt  # noqa: E402

CAM = smplpix.Camera(16, 12, [[20, 0, 8], [0, 20, 6], [0, 0, 1]])  # R = I, t = 0


def centred_points(n, seed):
    """n vertices that land on distinct pixel centres (so a small step moves no vertex to
    another pixel), at depths 1..3, plus two that collide in one pixel at distinct depths."""
    rng = np.random.default_rng(seed)
    pix = rng.choice(16 * 12, size=n, replace=False)
    px, py = pix % 16 + 0.5, pix // 16 + 0.5
    d = rng.uniform(1, 3, n)
    pts = np.stack([(px - 8) / 20 * d, (py - 6) / 20 * d, d], 1)
    extra = pts[0] * 1.2  # same pixel as vertex 0, farther away: loses
    return np.concatenate([pts, extra[None]])


def test_gradcheck_reference_path():
    with smplpix.Context(device=False) as ctx:
        v = torch.tensor(centred_points(12, 1), dtype=torch.float64, requires_grad=True)
        c = torch.rand(v.shape, dtype=torch.float64, generator=torch.Generator().manual_seed(2), requires_grad=True)

        def f(v, c):
            return spt.project(ctx, v, c, CAM, reference=True)
        # float32 arithmetic inside: steps of 1e-3 move depth by much more than its rounding
        assert torch.autograd.gradcheck(f, (v, c), eps=1e-3, atol=1e-3, rtol=1e-3)


def test_device_backward_equals_reference(ctx):
    v0 = centred_points(40, 3)
    g = torch.randn(1, 2, 12, 16, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(4))
    cams = [CAM, smplpix.Camera(16, 12, CAM.K, t=[0.02, 0.0, 0.1])]
    grads = []
    for ref in (False, True):
        v = torch.tensor(v0, requires_grad=True)
        c = torch.full(v.shape, 0.25, dtype=torch.float64, requires_grad=True)
        img = spt.project(ctx, v, c, cams, reference=ref)
        assert img.shape == (1, 2, 12, 16, 4) and img.dtype == torch.float64
        (img * g).sum().backward()
        grads.append((img.detach(), v.grad, c.grad))
    for a, b in zip(*grads):
        assert torch.equal(a, b)


def zbuffer_torch(v, c, cam):
    """A PyTorch3D-style hard z-buffer in plain torch: one point per pixel (points_per_pixel=1),
    the nearest z wins; pixel = floor of the perspective projection (our contract, where
    PyTorch3D would use NDC and a radius); background 1. Differentiable in colour and depth."""
    K = torch.tensor(cam.K, dtype=v.dtype)
    p = v @ torch.tensor(cam.R, dtype=v.dtype).T + torch.tensor(cam.t, dtype=v.dtype)
    q = p @ K.T
    d = q[:, 2]
    u, w = torch.floor(q[:, 0] / d).long(), torch.floor(q[:, 1] / d).long()
    ok = (d > 0) & (u >= 0) & (u < cam.width) & (w >= 0) & (w < cam.height)
    img = torch.ones(cam.height, cam.width, 4, dtype=v.dtype)
    best = {}
    for i in torch.nonzero(ok).flatten().tolist():
        k = (w[i].item(), u[i].item())
        if k not in best or d[i] < d[best[k]]:
            best[k] = i
    rows = torch.tensor([k[0] for k in best]), torch.tensor([k[1] for k in best])
    idx = torch.tensor(list(best.values()))
    img = img.index_put(rows, torch.cat([c[idx], d[idx, None]], 1))
    return img


def test_matches_torch_zbuffer_semantics(ctx):
    v0 = centred_points(30, 5)
    g = torch.randn(12, 16, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(6))
    out = []
    for fn in (lambda v, c: spt.project(ctx, v, c, CAM)[0, 0], lambda v, c: zbuffer_torch(v, c, CAM)):
        v = torch.tensor(v0, requires_grad=True)
        c = torch.rand(v.shape, dtype=torch.float64, generator=torch.Generator().manual_seed(7), requires_grad=True)
        img = fn(v, c)
        (img * g).sum().backward()
        out.append((img.detach(), v.grad, c.grad))
    (a, av, ac), (b, bv, bc) = out
    torch.testing.assert_close(a, b, atol=1e-6, rtol=1e-6)  # float32 inside smplpix
    torch.testing.assert_close(ac, bc, atol=1e-6, rtol=1e-6)  # the incoming gradient is rounded to float32
    torch.testing.assert_close(av, bv, atol=1e-5, rtol=1e-5)
    # the occluded vertex (last) gets nothing; with R = I and K's last row (0, 0, 1) the position
    # gradient is the depth channel's gradient, on z only (u, v are floored: no x, y gradient)
    assert torch.all(av[-1] == 0) and torch.all(ac[-1] == 0)
    assert torch.all(av[:, :2] == 0) and torch.count_nonzero(av[:, 2]) == 30


def test_positions_only_and_white(ctx):
    v = torch.tensor(centred_points(10, 8), requires_grad=True)
    img = spt.project(ctx, v, None, CAM)  # white
    assert torch.all(img[..., :3] == 1)
    img[..., 3].sum().backward()
    assert torch.count_nonzero(v.grad[:, 2]) == 10 and torch.all(v.grad[:, :2] == 0)
    with pytest.raises(ValueError, match="colors"):
        spt.project(ctx, v, torch.ones(3, 3, dtype=torch.float64), CAM)
