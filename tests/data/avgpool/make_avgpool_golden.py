#!/usr/bin/python3
"""Golden for tests/test_nn_avgpool.c: nn.AvgPool2d(3, stride=2, padding=[1, 1],
count_include_pad=False) (pix2pixHD's downsampler) forward and backward on odd and even sizes,
float64. Run: /usr/bin/python3 make_avgpool_golden.py > avgpool_golden.txt
Format: one record per line, "name count v0 v1 ...", values as %.17g; records suffixed by the case."""
import torch

torch.manual_seed(5)
pool = torch.nn.AvgPool2d(3, stride=2, padding=[1, 1], count_include_pad=False)


def rec(name, t):
    v = t.detach().reshape(-1).tolist()
    print(name, len(v), " ".join("%.17g" % v_ for v_ in v))


for case, (N, C, H, W) in enumerate([(2, 3, 7, 9), (1, 2, 6, 4), (1, 1, 1, 2)]):
    x = torch.randn(N, C, H, W, dtype=torch.float64).float().double().requires_grad_(True)
    y = pool(x)
    g = torch.randn(y.shape, dtype=torch.float64).float().double()
    y.backward(g)
    rec("shape%d" % case, torch.tensor([N, C, H, W]))
    rec("x%d" % case, x)
    rec("g%d" % case, g)
    rec("y%d" % case, y)
    rec("dx%d" % case, x.grad)
