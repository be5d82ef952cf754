#!/usr/bin/python3
"""Golden for tests/test_nn_vgg.c: the perceptual loss of the SMPLpix paper (eq. 5) on a VGG19
`features` stack with torchvision's layer order and state_dict names but 1/16 of the width
(base width 4: channels 4, 8, 16, 32, 32 instead of 64, 128, 256, 512, 512) and random weights, so
the file stays small. Run: /usr/bin/python3 make_vgg_golden.py (writes vgg_w4.safetensors and
vgg_golden.safetensors next to this script; deterministic).

  L = sum_{i=0..5} 2^-(5-i) mean |f_i(gt) - f_i(pred)|, f_0 = the image, f_1..f_5 = relu1_1,
  relu2_1, relu3_1, relu4_1, relu5_1 = features[0:2], [2:7], [7:12], [12:21], [21:30] of the
  ImageNet-normalised image.

vgg_w4.safetensors: features.N.weight/bias for the convs up to N = 28 (relu5_1's conv) plus a
classifier tensor the loader must ignore.
vgg_golden.safetensors: pred, gt [1,3,35,42] in [0,1]; loss [1]; grad = dL/dpred; spread.loss /
spread.grad: max |float32 - float64| / max |float64| of the same computation.
"""
import os
import sys

import numpy as np
import torch
import torch.nn as nn

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(HERE, "..", "unet"))
import make_unet_golden  # noqa: E402
from make_unet_golden import st_save  # noqa: E402

make_unet_golden.DTYPES[np.dtype("float64")] = "F64"

CFG = [1, 1, "M", 2, 2, "M", 4, 4, 4, 4, "M", 8, 8, 8, 8, "M", 8, 8, 8, 8, "M"]  # torchvision "E", / 64


class VGG19(nn.Module):
    def __init__(self, w):
        super().__init__()
        layers, cin = [], 3
        for v in CFG:
            if v == "M":
                layers.append(nn.MaxPool2d(kernel_size=2, stride=2))
            else:
                layers += [nn.Conv2d(cin, v * w, kernel_size=3, padding=1), nn.ReLU(inplace=False)]
                cin = v * w
        self.features = nn.Sequential(*layers)


def vgg_loss(model, pred, gt):
    mean = torch.tensor([0.485, 0.456, 0.406], dtype=pred.dtype).view(1, 3, 1, 1)
    std = torch.tensor([0.229, 0.224, 0.225], dtype=pred.dtype).view(1, 3, 1, 1)
    cuts = [(0, 2), (2, 7), (7, 12), (12, 21), (21, 30)]
    loss = (1.0 / 32) * (gt - pred).abs().mean()
    a, b = (gt - mean) / std, (pred - mean) / std
    for i, (s, e) in enumerate(cuts, start=1):
        for k in range(s, e):
            a, b = model.features[k](a), model.features[k](b)
        loss = loss + (1.0 / 2 ** (5 - i)) * (a - b).abs().mean()
    return loss


def main():
    torch.manual_seed(5)
    torch.set_num_threads(1)
    m = VGG19(4)
    with torch.no_grad():
        for mod in m.features:
            if isinstance(mod, nn.Conv2d):
                nn.init.kaiming_normal_(mod.weight, mode="fan_out", nonlinearity="relu")
                mod.bias.uniform_(-0.1, 0.1)
    # the convs up to features.28 (relu5_1) + one unused tensor; the loader must ignore the extra
    sd = [(k, v.numpy().copy()) for k, v in m.state_dict().items() if int(k.split(".")[1]) <= 28]
    sd.append(("classifier.0.weight", np.zeros((2, 3), dtype=np.float32)))
    st_save(os.path.join(HERE, "vgg_w4.safetensors"), sd, {"format": "pt"})
    pred = torch.rand(1, 3, 35, 42)
    gt = torch.rand(1, 3, 35, 42)
    p32 = pred.clone().requires_grad_(True)
    l32 = vgg_loss(m, p32, gt)
    l32.backward()
    m64 = VGG19(4).double()
    m64.load_state_dict({k: v.double() for k, v in m.state_dict().items()})
    p64 = pred.double().requires_grad_(True)
    l64 = vgg_loss(m64, p64, gt.double())
    l64.backward()
    sl = abs(l32.item() - l64.item()) / abs(l64.item())
    sg = ((p32.grad.double() - p64.grad).abs().max() / p64.grad.abs().max()).item()
    out = [("pred", pred.numpy().copy()), ("gt", gt.numpy().copy()),
           ("loss", np.array([l32.item()], dtype=np.float32)), ("grad", p32.grad.numpy().copy()),
           ("loss64", np.array([l64.item()], dtype=np.float64)), ("grad64", p64.grad.numpy().copy()),
           ("spread.loss", np.array([sl], dtype=np.float32)), ("spread.grad", np.array([sg], dtype=np.float32))]
    st_save(os.path.join(HERE, "vgg_golden.safetensors"), out, {"format": "pt"})
    print("loss %.8f (float64 %.10f), spreads %.3g %.3g" % (l32.item(), l64.item(), sl, sg))
    return 0


if __name__ == "__main__":
    sys.exit(main())
