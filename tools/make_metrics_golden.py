#!/usr/bin/env python3
"""Goldens for tests/test_metrics_ssim.c: image pairs (HxWx3 float32 .npy) and the PSNR / SSIM that
scikit-image gives for them (structural_similarity(gaussian_weights=True, sigma=1.5,
use_sample_covariance=False, data_range=1.0, channel_axis=-1), computed in float64), with the masked
values as smplpix/metrics.h defines them. Run: python3 tools/make_metrics_golden.py tests/data/metrics"""
import os
import sys

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

KW = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0)


def masked(p, t, m):
    """Masked PSNR (foreground MSE) and SSIM (mean of skimage's SSIM map over the valid foreground)."""
    fg = m != 0
    if not fg.any():
        return float("nan"), float("nan")
    mse = float(np.mean((p[fg] - t[fg]) ** 2))
    psnr = float("inf") if mse == 0 else 10 * np.log10(1 / mse)
    vals = []
    for c in range(3):
        _, s = structural_similarity(p[..., c], t[..., c], full=True, **KW)
        vals.append(s[5:-5, 5:-5][fg[5:-5, 5:-5]].mean())
    return psnr, float(np.mean(vals))


def main(out):
    rng = np.random.default_rng(20261124)
    cases = []
    a = rng.random((32, 32, 3), dtype=np.float32)
    cases.append(("random", a, rng.random((32, 32, 3), dtype=np.float32)))
    t = rng.random((37, 53, 3), dtype=np.float32)
    cases.append(("odd", np.clip(t + 0.1 * rng.standard_normal(t.shape).astype(np.float32), 0, 1), t))
    t = rng.random((20, 24, 3), dtype=np.float32)
    cases.append(("identical", t.copy(), t))
    cases.append(("constant", np.full((16, 19, 3), 0.3, np.float32), np.full((16, 19, 3), 0.7, np.float32)))
    t = rng.random((11, 11, 3), dtype=np.float32)
    cases.append(("min11", np.clip(t + 0.05 * rng.standard_normal(t.shape).astype(np.float32), 0, 1), t))
    # a smooth image with a foreground blob, for the masked values
    yy, xx = np.mgrid[0:41, 0:45]
    blob = ((yy - 20) ** 2 + (xx - 24) ** 2 < 12 ** 2)
    t = np.stack([0.5 + 0.4 * np.sin(xx / 5.0 + c) * np.cos(yy / 7.0) for c in range(3)], -1).astype(np.float32)
    p = t + np.where(blob[..., None], 0.08, 0.02) * rng.standard_normal(t.shape).astype(np.float32)
    cases.append(("masked", np.clip(p, 0, 1).astype(np.float32), t, blob.astype(np.float32)))
    lines = []
    for case in cases:
        name, p, t = case[0], case[1], case[2]
        np.save(os.path.join(out, name + "_pred.npy"), p)
        np.save(os.path.join(out, name + "_target.npy"), t)
        p64, t64 = p.astype(np.float64), t.astype(np.float64)
        psnr = peak_signal_noise_ratio(t64, p64, data_range=1.0) if not np.array_equal(p, t) else float("inf")
        ssim = structural_similarity(p64, t64, channel_axis=-1, **KW)
        pf, sf = float("nan"), float("nan")
        if len(case) > 3:
            np.save(os.path.join(out, name + "_mask.npy"), case[3])
            pf, sf = masked(p64, t64, case[3])
        lines.append("%s %.17g %.17g %.17g %.17g" % (name, psnr, ssim, pf, sf))
    with open(os.path.join(out, "expected.txt"), "w") as f:
        f.write("# name psnr ssim psnr_fg ssim_fg (scikit-image %s; made by tools/make_metrics_golden.py)\n"
                % __import__("skimage").__version__)
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/metrics")
