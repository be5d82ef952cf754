#!/usr/bin/env python3
"""LPIPS golden for tests/test_metrics_lpips.c, made with the `lpips` PyPI package (0.1.4) on a
random AlexNet: lpips.LPIPS(net='alex', pretrained=False, pnet_rand=True) (no download), whose
weights are then replaced by values the C test regenerates bit for bit (splitmix64 of the element
index, see weights()), so no weight file is committed. Writes image pairs (HxWx3 float32 .npy) and
lpips_expected.txt (LPIPS in float64, and float32 for the float32-vs-float64 spread), and
lpips_masked_expected.txt: the masked LPIPS of the committed pairs, the mean over a rectangle's
pixels (x in [W/4, 3W/4), y in [H/5, 4H/5), integer division) of lpips.LPIPS(spatial=True)'s map
(each layer's distance map upsampled to the image size, bilinear, align_corners=False, summed).
With --masked it writes only that file, from the pairs already in the folder.
Needs: python3 -m venv --system-site-packages /tmp/lp && /tmp/lp/bin/pip install --no-deps lpips tqdm
(and Debian's python3-torch, python3-torchvision). Run: /tmp/lp/bin/python tools/make_lpips_golden.py tests/data/metrics"""
import os
import sys

import numpy as np
import torch
import lpips


def splitmix_uniform(seed, n):
    """u[i] in [0,1): splitmix64(seed * 2^32 + i) >> 11, times 2^-53 (tests/test_metrics_lpips.c: uniform())."""
    z = (np.arange(n, dtype=np.uint64) + np.uint64(seed << 32))
    with np.errstate(over="ignore"):
        z = z + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0 ** -53


def weights(sd):
    """Replace the conv weights/biases and the linear heads: tensor j of ORDER gets
    (2u - 1) * a with a = sqrt(6 / fan_in) for weights, 0.1 for biases; heads get 0.2u (non-negative,
    like the trained ones). Values are rounded to float32."""
    order = ["net.slice1.0", "net.slice2.3", "net.slice3.6", "net.slice4.8", "net.slice5.10"]
    seed = 1
    for name in order:
        w = sd[name + ".weight"]
        fan_in = w[0].numel()
        u = splitmix_uniform(seed, w.numel())
        sd[name + ".weight"] = torch.from_numpy(((2 * u - 1) * np.sqrt(6.0 / fan_in)).astype(np.float32).reshape(w.shape))
        seed += 1
        b = sd[name + ".bias"]
        u = splitmix_uniform(seed, b.numel())
        sd[name + ".bias"] = torch.from_numpy(((2 * u - 1) * 0.1).astype(np.float32).reshape(b.shape))
        seed += 1
    for l in range(5):
        k = "lin%d.model.1.weight" % l
        u = splitmix_uniform(seed, sd[k].numel())
        sd[k] = torch.from_numpy((0.2 * u).astype(np.float32).reshape(sd[k].shape))
        seed += 1
    return sd


def model(spatial=False):
    torch.manual_seed(0)
    m = lpips.LPIPS(net="alex", pretrained=False, pnet_rand=True, spatial=spatial, verbose=False)
    sd = weights(m.state_dict())
    m.load_state_dict(sd)
    m.eval()
    return m


def both_precisions(m, p, t):
    """The model's output on the pair (HxWx3 arrays in [0,1]) in float64, then in float32."""
    out = []
    for dt in (torch.float64, torch.float32):
        mm = m.to(dt)
        a = torch.from_numpy(p).permute(2, 0, 1)[None].to(dt)
        b = torch.from_numpy(t).permute(2, 0, 1)[None].to(dt)
        with torch.no_grad():
            out.append(mm(a, b, normalize=True))
    return out


def masked(out, names=("lp_random", "lp_odd", "lp_same")):
    m = model(spatial=True)
    lines = []
    for name in names:
        p = np.load(os.path.join(out, name + "_pred.npy"))
        t = np.load(os.path.join(out, name + "_target.npy"))
        h, w = p.shape[:2]
        fg = np.zeros((h, w), bool)
        fg[h // 5:(4 * h) // 5, w // 4:(3 * w) // 4] = True
        vals = [float(v[0, 0].numpy()[fg].mean()) for v in both_precisions(m, p, t)]
        lines.append("%s %.17g %.17g" % (name, vals[0], vals[1]))
    with open(os.path.join(out, "lpips_masked_expected.txt"), "w") as f:
        f.write("# name masked_lpips_float64 masked_lpips_float32: mean over the rectangle x in [W/4, 3W/4), y in "
                "[H/5, 4H/5) of LPIPS(spatial=True) (lpips %s, torch %s; tools/make_lpips_golden.py --masked)\n"
                % (lpips.__version__ if hasattr(lpips, "__version__") else "0.1.4", torch.__version__))
        f.write("\n".join(lines) + "\n")


def main(out):
    m = model()
    rng = np.random.default_rng(7)
    pairs = []
    t = rng.random((48, 40, 3), dtype=np.float32)
    pairs.append(("lp_random", rng.random((48, 40, 3), dtype=np.float32), t))
    yy, xx = np.mgrid[0:37, 0:33]
    t = np.stack([0.5 + 0.4 * np.sin(xx / 4.0 + c) * np.cos(yy / 6.0) for c in range(3)], -1).astype(np.float32)
    p = np.clip(t + 0.05 * rng.standard_normal(t.shape), 0, 1).astype(np.float32)
    pairs.append(("lp_odd", p, t))
    t = rng.random((31, 31, 3), dtype=np.float32)
    pairs.append(("lp_same", t.copy(), t))
    lines = []
    for name, p, t in pairs:
        np.save(os.path.join(out, name + "_pred.npy"), p)
        np.save(os.path.join(out, name + "_target.npy"), t)
        vals = [float(v.flatten()[0]) for v in both_precisions(m, p, t)]
        lines.append("%s %.17g %.17g" % (name, vals[0], vals[1]))
    with open(os.path.join(out, "lpips_expected.txt"), "w") as f:
        f.write("# name lpips_float64 lpips_float32 (lpips %s, torch %s; made by tools/make_lpips_golden.py)\n"
                % (lpips.__version__ if hasattr(lpips, "__version__") else "0.1.4", torch.__version__))
        f.write("\n".join(lines) + "\n")
    masked(out)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--masked"]
    folder = args[0] if args else "tests/data/metrics"
    if "--masked" in sys.argv[1:]:
        masked(folder)
    else:
        main(folder)
