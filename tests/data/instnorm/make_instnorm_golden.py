#!/usr/bin/python3
"""Golden for tests/test_nn_instnorm.c: nn.InstanceNorm2d(C, affine=False) (eps 1e-5, biased
variance, no running statistics) forward and backward (dx for a fixed upstream gradient g), on an
odd-sized input with a per-plane offset (so the two-pass variance matters) in float64.
Run: /usr/bin/python3 make_instnorm_golden.py > instnorm_golden.txt
Format: one record per line, "name count v0 v1 ...", values as %.17g."""
import torch

torch.manual_seed(11)
N, C, H, W = 2, 3, 5, 7
x = (torch.randn(N, C, H, W, dtype=torch.float64) * 2 + torch.arange(N * C, dtype=torch.float64).reshape(N, C, 1, 1) * 3)
x = x.float().double().requires_grad_(True)  # values exact in float32
g = torch.randn(N, C, H, W, dtype=torch.float64).float().double()
y = torch.nn.InstanceNorm2d(C, affine=False)(x)
y.backward(g)


def rec(name, t):
    v = t.detach().reshape(-1).tolist()
    print(name, len(v), " ".join("%.17g" % v_ for v_ in v))


rec("shape", torch.tensor([N, C, H, W]))
rec("x", x)
rec("g", g)
rec("y", y)
rec("dx", x.grad)
