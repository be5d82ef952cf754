#!/usr/bin/python3
"""Golden for tests/test_nn_pool.c: F.max_pool2d(x, 2) (stride 2, floor mode) on odd sizes with
many ties (values from {0, 1, 2}) and an all -inf window, forward and backward (dx for a fixed
upstream gradient): checks PyTorch's tie rule (first maximum in row-major window order).
Run with Debian's python3-torch: /usr/bin/python3 make_pool_golden.py > pool_golden.txt
Format: one record per line, "name count v0 v1 ...", float32 values as %.9g."""
import torch
import torch.nn.functional as F

torch.manual_seed(9)
N, C, H, W = 2, 3, 7, 9
x = torch.randint(0, 3, (N, C, H, W)).float()
x[0, 0, 0:2, 0:2] = float("-inf")
g = torch.randn(N, C, H // 2, W // 2)


def rec(name, t):
    v = t.detach().reshape(-1).tolist()
    print(name, len(v), " ".join("%.9g" % v_ for v_ in v))


print("shape 4", N, C, H, W)
rec("x", x)
rec("g", g)
xr = x.clone().requires_grad_(True)
y = F.max_pool2d(xr, 2)
y.backward(g)
rec("y", y)
rec("dx", xr.grad)
