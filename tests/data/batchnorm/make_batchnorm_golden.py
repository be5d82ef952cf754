#!/usr/bin/python3
"""Golden for tests/test_nn_batchnorm.c: torch.nn.BatchNorm2d (momentum 0.1, eps 1e-5, affine)
in train mode for two steps (output, running_mean, running_var), the backward of step 1
(dx, dweight, dbias for a fixed upstream gradient), and eval mode after step 2.
Run with Debian's python3-torch: /usr/bin/python3 make_batchnorm_golden.py > batchnorm_golden.txt
Format: one record per line, "name count v0 v1 ...", float32 values as %.9g."""
import torch

torch.manual_seed(77)
N, C, H, W = 2, 3, 5, 7
bn = torch.nn.BatchNorm2d(C)
with torch.no_grad():
    bn.weight.copy_(torch.rand(C) + 0.5)
    bn.bias.copy_(torch.randn(C))
    bn.running_mean.copy_(torch.randn(C))
    bn.running_var.copy_(torch.rand(C) + 0.5)


def rec(name, t):
    v = t.detach().reshape(-1).tolist()
    print(name, len(v), " ".join("%.9g" % x for x in v))


print("shape 4", N, C, H, W)
rec("weight", bn.weight)
rec("bias", bn.bias)
rec("rm0", bn.running_mean)
rec("rv0", bn.running_var)
x1 = (torch.randn(N, C, H, W) * 2 + 3).requires_grad_(True)
x2 = torch.randn(N, C, H, W) * 0.5 - 1
g1 = torch.randn(N, C, H, W)
rec("x1", x1)
rec("x2", x2)
rec("g1", g1)
bn.train()
y1 = bn(x1)
rec("y1", y1)
rec("rm1", bn.running_mean)
rec("rv1", bn.running_var)
y1.backward(g1)
rec("dx1", x1.grad)
rec("dweight1", bn.weight.grad)
rec("dbias1", bn.bias.grad)
y2 = bn(x2)
rec("y2", y2)
rec("rm2", bn.running_mean)
rec("rv2", bn.running_var)
bn.eval()
rec("yeval", bn(x1))
