#!/usr/bin/python3
"""PyTorch peer of benchmarks/bench_gan_step.c: one stage-2 training step of the SMPLpix paper in
PyTorch (CPU, all cores): the milesial UNet generator, pix2pixHD's MultiscaleDiscriminator (3
scales, n_layers 3, getIntermFeat, InstanceNorm, LSGAN) conditional on the RGB-D input and a
frozen VGG19 perceptual loss (eq. 5), random weights. The step is pix2pixHD's: D on the detached
fake, on the real, on the fake; loss_G = L_VGG + L_GAN + 0.1 L_FM; Adam steps for G and D. The
VGG features of the target are computed under no_grad. Minimum over reps after one warm-up.

  /usr/bin/python3 benchmarks/peer_gan_step_torch.py [--width 64] [--disc-width 64] [--size 308x410]
                                                     [--batch 1] [--reps 2]
"""
import argparse
import os
import resource
import sys
import time

import torch
import torch.nn.functional as F

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
for sub in ("unet", "patchgan", "vgg"):
    sys.path.insert(0, os.path.join(HERE, "..", "tests", "data", sub))
from make_patchgan_golden import MultiscaleD, adam_steps, lsgan  # noqa: E402
from make_unet_golden import UNet  # noqa: E402
from make_vgg_golden import VGG19  # noqa: E402


def vgg_feats(vgg, x):
    mean = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
    std = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)
    h, out = (x - mean) / std, [x]
    for s, e in [(0, 2), (2, 7), (7, 12), (12, 21), (21, 30)]:
        for k in range(s, e):
            h = vgg.features[k](h)
        out.append(h)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--disc-width", type=int, default=64)
    ap.add_argument("--size", default="308x410")
    ap.add_argument("--batch", type=int, default=1)
    ap.add_argument("--reps", type=int, default=2)
    a = ap.parse_args()
    h, w = (int(v) for v in a.size.split("x"))
    torch.set_num_threads(os.cpu_count())
    torch.manual_seed(0)
    G, D, vgg = UNet(a.width), MultiscaleD(7, a.disc_width, 3), VGG19(64)
    for p in vgg.parameters():
        p.requires_grad_(False)
    G.train()
    optG = torch.optim.Adam(G.parameters(), lr=1e-5)
    optD = torch.optim.Adam(D.parameters(), lr=1e-5)
    x, real = torch.rand(a.batch, 4, h, w), torch.rand(a.batch, 3, h, w)
    best = 1e30
    for r in range(a.reps + 1):
        t0 = time.perf_counter()
        fake = G(x)
        loss_d_fake = lsgan(D(torch.cat((x, fake.detach()), 1)), False)
        pred_real = D(torch.cat((x, real), 1))
        loss_d_real = lsgan(pred_real, True)
        pred_fake = D(torch.cat((x, fake), 1))
        loss_g_gan = lsgan(pred_fake, True)
        fm = 0
        for i in range(3):
            for j in range(len(pred_fake[i]) - 1):
                fm = fm + (1.0 / 3) * F.l1_loss(pred_fake[i][j], pred_real[i][j].detach())
        with torch.no_grad():
            fr = vgg_feats(vgg, real)
        ff = vgg_feats(vgg, fake)
        lv = sum((1.0 / 2 ** (5 - i)) * F.l1_loss(ff[i], fr[i]) for i in range(6))
        loss_g = lv + loss_g_gan + 0.1 * fm
        loss_d = 0.5 * (loss_d_fake + loss_d_real)
        adam_steps(optG, loss_g, optD, loss_d)
        t = time.perf_counter() - t0
        if r > 0:
            best = min(best, t)
        print("  %s %.1f ms" % ("step" if r else "warm-up", 1e3 * t), file=sys.stderr)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print("torch %s: stage-2 step, %dx4x%dx%d: %.1f ms (min of %d)" % (torch.__version__, a.batch, h, w, 1e3 * best, a.reps))
    print("ROW impl=torch mode=gan_step width=%d batch=%d h=%d w=%d reps=%d ms=%.3f mem_bytes=%d mem_kind=peak_rss"
          % (a.width, a.batch, h, w, a.reps, 1e3 * best, rss))
    return 0


if __name__ == "__main__":
    sys.exit(main())
