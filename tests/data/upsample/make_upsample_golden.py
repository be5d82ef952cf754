#!/usr/bin/python3
"""Golden for tests/test_nn_upsample.c: F.interpolate(x, scale_factor=2, mode="bilinear") with
align_corners True and False, forward and backward (dx for a fixed upstream gradient), on an
odd-sized input and on a 1-pixel-high one.
Run with Debian's python3-torch: /usr/bin/python3 make_upsample_golden.py > upsample_golden.txt
Format: one record per line, "name count v0 v1 ...", float32 values as %.9g."""
import torch
import torch.nn.functional as F

torch.manual_seed(5)


def rec(name, t):
    v = t.detach().reshape(-1).tolist()
    print(name, len(v), " ".join("%.9g" % x for x in v))


for case, (n, c, h, w) in enumerate([(2, 2, 3, 5), (1, 1, 1, 4)]):
    x = torch.randn(n, c, h, w)
    g = torch.randn(n, c, 2 * h, 2 * w)
    print("shape%d 4" % case, n, c, h, w)
    rec("x%d" % case, x)
    rec("g%d" % case, g)
    for ac in (True, False):
        xr = x.clone().requires_grad_(True)
        y = F.interpolate(xr, scale_factor=2, mode="bilinear", align_corners=ac)
        y.backward(g)
        rec("y%d_%s" % (case, "ac" if ac else "noac"), y)
        rec("dx%d_%s" % (case, "ac" if ac else "noac"), xr.grad)
