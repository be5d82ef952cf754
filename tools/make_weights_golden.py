#!/usr/bin/env python3
"""Goldens for tests/test_weights_golden.c: the pretrained networks of `make weights` against outside
code. Reads ${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/{lpips_alex,vgg16}.safetensors (or --dir)
and writes tests/data/weights/:

  lpips_alex_expected.txt  LPIPS of 24 image pairs (6 sizes from 31x31 to 64x48, 4 degrees of
      difference) by the lpips PyPI package (0.1.4): lpips.LPIPS(net='alex') with its own v0.1
      heads (checked bit-equal to the converted file's) and its AlexNet loaded from
      lpips_alex.safetensors (load_state_dict, strict), in float64 and float32. The images are not
      stored: pair j's pixels are splitmix64 functions of (seed, index) that the C test regenerates
      (pair_images below, tests/lpips_weights.h).
  vgg16_golden.safetensors  the VGG16 loss as the official SMPLpix code computes it
      (tests/data/vgg/make_vgg16_golden.py: smplpix_vgg16_loss) on torchvision's vgg16().features
      loaded from vgg16.safetensors (strict), pred and gt [2,3,20,24]: loss and dL/dpred in
      float32 and float64, and their spreads.

It also checks that tools/lpips_to_safetensors.py, given the lpips package's state_dict of the same
model, writes the same tensors as the converted file (the two kinds of --lpips file are
interchangeable). Needs torch, torchvision and the lpips package, e.g.
  python3 -m venv --system-site-packages /tmp/lpw && /tmp/lpw/bin/pip install --no-deps lpips==0.1.4
  (Debian: python3-torch python3-torchvision python3-scipy python3-tqdm)
  /tmp/lpw/bin/python tools/make_weights_golden.py"""
import argparse
import hashlib
import os
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests", "data", "vgg"))
import lpips  # noqa: E402
from make_lpips_golden import splitmix_uniform  # noqa: E402  (tools/; tests/lpips_weights.h draws the same)
import torchvision  # noqa: E402
import lpips_to_safetensors  # noqa: E402
import make_vgg16_golden  # noqa: E402
import spx_safetensors  # noqa: E402

SIZES = [(31, 31), (32, 40), (40, 33), (48, 48), (37, 53), (64, 48)]  # (height, width)
ALPHAS = [1.0 / 16, 1.0 / 4, 1.0 / 2, 1.0]


def pair_images(j):
    """Pair j (0..23): HxWx3 float32 pred = a, target = (1 - alpha) a + alpha b (in double, then
    rounded), a = u(1000 + j, i), b = u(2000 + j, i), i the HWC element index."""
    h, w = SIZES[j // 4]
    alpha = ALPHAS[j % 4]
    n = h * w * 3
    a, b = splitmix_uniform(1000 + j, n), splitmix_uniform(2000 + j, n)
    t = (1.0 - alpha) * a + alpha * b
    return h, w, alpha, a.astype(np.float32).reshape(h, w, 3), t.astype(np.float32).reshape(h, w, 3)


def sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def lpips_golden(path, out_dir):
    ours = spx_safetensors.st_load(path)
    m = lpips.LPIPS(net="alex", pretrained=True, pnet_rand=True, verbose=False)
    sd = m.state_dict()
    for l in range(5):  # the package's own v0.1 heads, as loaded by pretrained=True
        k = "lin%d.model.1.weight" % l
        if not np.array_equal(sd[k].numpy(), ours[k]):
            sys.exit("%s: %s differs from the lpips package's v0.1 head" % (path, k))
    load = {k: torch.from_numpy(v) for k, v in ours.items()}
    for l in range(5):  # the package's ModuleList `lins` holds the same heads under a second name
        load["lins.%d.model.1.weight" % l] = load["lin%d.model.1.weight" % l]
    m.load_state_dict(load, strict=True)
    m.eval()
    # tools/lpips_to_safetensors.py on the package's state_dict of this model: the same tensors
    again = lpips_to_safetensors.convert(full={k: v.detach().numpy() for k, v in m.state_dict().items()})
    if sorted(again) != sorted(ours) or any(not np.array_equal(np.asarray(again[k], "<f4"), ours[k]) for k in ours):
        sys.exit("%s: tools/lpips_to_safetensors.py writes other tensors for the same model" % path)
    lines = []
    for j in range(4 * len(SIZES)):
        h, w, alpha, p, t = pair_images(j)
        vals = []
        for dt in (torch.float64, torch.float32):
            mm = m.to(dt)
            a = torch.from_numpy(p).permute(2, 0, 1)[None].to(dt)
            b = torch.from_numpy(t).permute(2, 0, 1)[None].to(dt)
            with torch.no_grad():
                vals.append(float(mm(a, b, normalize=True).flatten()[0]))
        lines.append("%d %d %d %.17g %.17g %.17g" % (j, h, w, alpha, vals[0], vals[1]))
    with open(os.path.join(out_dir, "lpips_alex_expected.txt"), "w") as f:
        f.write("# pair height width alpha lpips_float64 lpips_float32: lpips %s (net='alex', its v0.1 heads), torch "
                "%s, AlexNet from lpips_alex.safetensors sha256 %s (make weights); tools/make_weights_golden.py\n"
                % (getattr(lpips, "__version__", "0.1.4"), torch.__version__, sha256(path)))
        f.write("\n".join(lines) + "\n")
    print("LPIPS: %d pairs, values %.4f .. %.4f" % (len(lines), min(float(l.split()[4]) for l in lines),
                                                   max(float(l.split()[4]) for l in lines)))


def vgg16_golden(path, out_dir):
    feats = torchvision.models.vgg16().features  # no download: the weights come from the file
    sd = spx_safetensors.st_load(path)
    feats.load_state_dict({k[len("features."):]: torch.from_numpy(v) for k, v in sd.items()}, strict=True)
    torch.manual_seed(23)
    pred = torch.rand(2, 3, 20, 24)
    gt = torch.rand(2, 3, 20, 24)
    out = make_vgg16_golden.golden(feats, pred, gt)
    spx_safetensors.DTYPES[np.dtype("float64")] = "F64"
    spx_safetensors.st_save(os.path.join(out_dir, "vgg16_golden.safetensors"), out,
                            {"format": "pt", "weights_sha256": sha256(path), "torch": torch.__version__})
    d = dict(out)
    print("VGG16: loss %.8f (float64 %.10f), spreads %.3g %.3g" % (d["loss"][0], d["loss64"][0], d["spread.loss"][0],
                                                                  d["spread.grad"][0]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    cache = os.environ.get("SPX_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "smplpix")
    ap.add_argument("--dir", default=os.path.join(cache, "weights"), help="the weights (default: the cache's)")
    ap.add_argument("--out", default=os.path.join(HERE, "..", "tests", "data", "weights"))
    a = ap.parse_args()
    torch.set_num_threads(1)
    os.makedirs(a.out, exist_ok=True)
    lpips_golden(os.path.join(a.dir, "lpips_alex.safetensors"), a.out)
    vgg16_golden(os.path.join(a.dir, "vgg16.safetensors"), a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
