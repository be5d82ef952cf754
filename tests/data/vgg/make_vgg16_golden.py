#!/usr/bin/python3
"""Golden for tests/test_nn_vgg16.c: the VGG16 perceptual loss as the official SMPLpix code computes
it (its vgg.py Vgg16Features with layers_weights [1, 1/16, 1/8, 1/4, 1], as its training.py builds
it, and torch.nn.L1Loss), written here from that definition:

  pieces = x, vgg16().features[0:4](x) (relu1_2), then [4:9] (relu2_2), [9:16] (relu3_3),
  [16:23] (relu4_3), each flattened per sample (no ImageNet normalisation of x);
  F(x) = cat(1 * x, 1/16 * relu1_2, 1/8 * relu2_2, 1/4 * relu3_3, 1 * relu4_3) along dim 1;
  loss = L1Loss()(F(pred), F(gt)) = mean over all elements of |F(pred) - F(gt)|.

On a `features` stack with torchvision's layer order and state_dict names (cfg "D") at 1/16 of
the width (base 4: channels 4, 8, 16, 32) and random weights, so the file stays small. Run:
/usr/bin/python3 make_vgg16_golden.py (writes vgg16_w4.safetensors and vgg16_golden.safetensors
next to this script; deterministic). tools/make_weights_golden.py uses the same reference
(smplpix_vgg16_loss) on torchvision's vgg16().features with the real weights.

vgg16_w4.safetensors: features.N.weight/bias for the convs up to N = 21 (relu4_3's conv) plus a
classifier tensor the loader must ignore.
vgg16_golden.safetensors: pred, gt [2,3,24,29] in [0,1]; loss [1]; grad = dL/dpred (float32
run) and loss64, grad64 (float64 run); spread.loss / spread.grad: max |float32 - float64| / max
|float64| of the same computation.
"""
import os
import sys

import numpy as np
import torch
import torch.nn as nn

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(HERE, "..", "..", "..", "tools"))
import spx_safetensors  # noqa: E402

spx_safetensors.DTYPES[np.dtype("float64")] = "F64"

SLICES = [(0, 4), (4, 9), (9, 16), (16, 23)]
WEIGHTS = [1.0, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0]
CFG_D = [1, 1, "M", 2, 2, "M", 4, 4, 4, "M", 8, 8, 8, "M"]  # torchvision "D" up to pool4, / 64


def smplpix_vgg16_features(features, x):
    pieces, h = [x.flatten(start_dim=1)], x
    for a, b in SLICES:
        for k in range(a, b):
            h = features[k](h)
        pieces.append(h.flatten(start_dim=1))
    return torch.cat([w * p for w, p in zip(WEIGHTS, pieces)], 1)


def smplpix_vgg16_loss(features, pred, gt):
    return nn.L1Loss()(smplpix_vgg16_features(features, pred), smplpix_vgg16_features(features, gt))


def vgg16_features(width):
    layers, cin = [], 3
    for v in CFG_D:
        if v == "M":
            layers.append(nn.MaxPool2d(kernel_size=2, stride=2))
        else:
            layers += [nn.Conv2d(cin, v * width, kernel_size=3, padding=1), nn.ReLU(inplace=True)]
            cin = v * width
    return nn.Sequential(*layers)


def golden(features, pred, gt):
    """Loss and dL/dpred in float32 and float64, and their relative spreads."""
    features = features.float().eval()
    p32 = pred.clone().requires_grad_(True)
    l32 = smplpix_vgg16_loss(features, p32, gt)
    l32.backward()
    f64 = features.double()  # .double() converts in place: the float32 run is done
    p64 = pred.double().requires_grad_(True)
    l64 = smplpix_vgg16_loss(f64, p64, gt.double())
    l64.backward()
    features.float()
    sl = abs(l32.item() - l64.item()) / abs(l64.item())
    sg = ((p32.grad.double() - p64.grad).abs().max() / p64.grad.abs().max()).item()
    return [("pred", pred.numpy().copy()), ("gt", gt.numpy().copy()),
            ("loss", np.array([l32.item()], dtype=np.float32)), ("grad", p32.grad.numpy().copy()),
            ("loss64", np.array([l64.item()], dtype=np.float64)), ("grad64", p64.grad.numpy().copy()),
            ("spread.loss", np.array([sl], dtype=np.float32)), ("spread.grad", np.array([sg], dtype=np.float32))]


def main():
    torch.manual_seed(11)
    torch.set_num_threads(1)
    feats = vgg16_features(4)
    with torch.no_grad():
        for mod in feats:
            if isinstance(mod, nn.Conv2d):
                nn.init.kaiming_normal_(mod.weight, mode="fan_out", nonlinearity="relu")
                mod.bias.uniform_(-0.1, 0.1)
    sd = [("features." + k, v.numpy().copy()) for k, v in feats.state_dict().items() if int(k.split(".")[0]) <= 21]
    sd.append(("classifier.0.weight", np.zeros((2, 3), dtype=np.float32)))
    spx_safetensors.st_save(os.path.join(HERE, "vgg16_w4.safetensors"), sd, {"format": "pt"})
    pred = torch.rand(2, 3, 24, 29)
    gt = torch.rand(2, 3, 24, 29)
    out = golden(feats, pred, gt)
    spx_safetensors.st_save(os.path.join(HERE, "vgg16_golden.safetensors"), out, {"format": "pt"})
    d = dict(out)
    print("loss %.8f (float64 %.10f), spreads %.3g %.3g" % (d["loss"][0], d["loss64"][0], d["spread.loss"][0],
                                                           d["spread.grad"][0]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
