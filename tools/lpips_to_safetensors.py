#!/usr/bin/env python3
"""Convert LPIPS (net='alex', version 0.1) weights to the one safetensors file `smplpix eval --lpips`
reads (names and layout: lib/include/smplpix/metrics.h).

Either from a whole LPIPS state_dict:
    python3 -c "import lpips, torch; torch.save(lpips.LPIPS(net='alex').state_dict(), 'lpips_alex_full.pth')"
    tools/lpips_to_safetensors.py --state-dict lpips_alex_full.pth -o lpips_alex.safetensors
or from the two files it is made of: the lpips package's linear heads (lpips/weights/v0.1/alex.pth,
names lin0..lin4.model.1.weight) and torchvision's ImageNet AlexNet (alexnet-owt-7be5be79.pth, names
features.N.weight/bias):
    tools/lpips_to_safetensors.py --lin alex.pth --alexnet alexnet-owt-7be5be79.pth -o lpips_alex.safetensors
Needs torch only to read .pth files; the output is float32."""
import argparse
import sys

import numpy as np
from spx_safetensors import st_save

# torchvision alexnet.features index -> the lpips package's slice name
SLICES = {0: "net.slice1.0", 3: "net.slice2.3", 6: "net.slice3.6", 8: "net.slice4.8", 10: "net.slice5.10"}
SHAPES = {0: (64, 3, 11, 11), 3: (192, 64, 5, 5), 6: (384, 192, 3, 3), 8: (256, 384, 3, 3), 10: (256, 256, 3, 3)}
# the lpips package's ScalingLayer constants (also in its state_dict as buffers)
SHIFT = [-.030, -.088, -.188]
SCALE = [.458, .448, .450]


def load_pth(path):
    import torch
    sd = torch.load(path, map_location="cpu")
    if isinstance(sd, dict) and "state_dict" in sd:
        sd = sd["state_dict"]
    return {k: v.detach().cpu().numpy() for k, v in sd.items()}


def convert(full=None, lin=None, alexnet=None):
    out = {}
    src = full if full is not None else {}
    for idx, name in SLICES.items():
        for part in ("weight", "bias"):
            key = name + "." + part
            if full is not None:
                a = src.get(key)
            else:
                a = alexnet.get("features.%d.%s" % (idx, part))
            if a is None:
                sys.exit("missing tensor %s" % key)
            want = SHAPES[idx] if part == "weight" else SHAPES[idx][:1]
            if tuple(a.shape) != want:
                sys.exit("tensor %s has shape %s, expected %s" % (key, tuple(a.shape), want))
            out[key] = a
    heads = full if full is not None else lin
    for l in range(5):
        key = "lin%d.model.1.weight" % l
        a = heads.get(key)
        want = (1, SHAPES[list(SLICES)[l]][0], 1, 1)
        if a is None or tuple(a.shape) != want:
            sys.exit("tensor %s is missing or not of shape %s" % (key, want))
        out[key] = a
    out["scaling_layer.shift"] = np.asarray(src.get("scaling_layer.shift", np.reshape(SHIFT, (1, 3, 1, 1))))
    out["scaling_layer.scale"] = np.asarray(src.get("scaling_layer.scale", np.reshape(SCALE, (1, 3, 1, 1))))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--state-dict", help="a whole LPIPS(net='alex') state_dict (.pth)")
    ap.add_argument("--lin", help="the lpips package's weights/v0.1/alex.pth")
    ap.add_argument("--alexnet", help="torchvision's AlexNet state_dict (.pth)")
    ap.add_argument("-o", "--out", required=True)
    a = ap.parse_args()
    if a.state_dict:
        t = convert(full=load_pth(a.state_dict))
    elif a.lin and a.alexnet:
        t = convert(lin=load_pth(a.lin), alexnet=load_pth(a.alexnet))
    else:
        ap.error("give --state-dict, or --lin and --alexnet")
    st_save(a.out, [(k, np.ascontiguousarray(t[k], dtype="<f4")) for k in sorted(t)])  # F32, names sorted


if __name__ == "__main__":
    main()
