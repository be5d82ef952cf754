#!/usr/bin/python3
"""Golden data for one stage-2 training step (tests/test_nn_patchgan.c): the SMPLpix UNet (width 4)
as the generator and pix2pixHD's multi-scale PatchGAN (3 scales, n_layers 3, getIntermFeat, ndf 4,
InstanceNorm, LSGAN), conditional on the RGB-D input (7 input channels).

Needs PyTorch (Debian python3-torch) and NumPy:
  /usr/bin/python3 tests/data/patchgan/make_patchgan_golden.py
writes, next to this script (deterministic; commit them):
  G.safetensors   the generator's initial state_dict (the UNet of ../unet/make_unet_golden.py;
                  conv weights rounded to float16 and stored as F16, batch-norm tensors randomised)
  D.safetensors   the discriminator's initial state_dict under pix2pixHD's names
                  (scale{i}_layer{j}.0.weight / .bias), F32 values that are exact in float16
  step.safetensors
    input [1,4,37,53], target [1,3,37,53]
    loss.{rec,gan,fm,d_fake,d_real}: the terms before the step
    after.G.<name>, after.D.<name>: every parameter after the step (tensors larger than 2048
      elements as a strided sample + aftersum.<name> = [sum g*r, sum |g|], as in the UNet golden)
    spread.<name>: max |float32 - float64| / max |float64| of each tensor after the same step in
      float64 (the test's tolerance is max(1e-4, 10 x spread))
  step_vgg.safetensors: the same for the paper's stage 2, L_VGG instead of L1 as the generator's
    reconstruction term, with the small random VGG19 of ../vgg/vgg_w4.safetensors

The step is pix2pixHD's: fake = G(x); D on [x, fake.detach()] -> loss_D_fake (target 0); D on
[x, real] -> loss_D_real (target 1); D on [x, fake] -> loss_G_GAN (target 1); feature matching
sum_k sum_{l<4} (1/3) (4/4) L1(D_k^l(fake), D_k^l(real).detach()); loss_G = L1(fake, real) + loss_G_GAN
+ 0.1 * FM; loss_D = 0.5 (loss_D_fake + loss_D_real); optG.zero_grad, loss_G.backward, optG.step,
then optD.zero_grad, loss_D.backward, optD.step. Adam lr 1e-3, betas (0.9, 0.999), eps 1e-3 (see the
UNet golden for why not 1e-8), the same for G and D.

--check D.safetensors loads a discriminator file written by smplpix into MultiscaleDiscriminator
with load_state_dict(strict=True) (optimizer.* tensors set aside) and prints its tensor count.
"""
import copy
import os
import sys

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "unet"))
sys.dont_write_bytecode = True
from make_unet_golden import UNet, fp16_weights_random_bn, sampled, st_load, st_save  # noqa: E402

sys.path.insert(0, os.path.join(HERE, "..", "vgg"))
from make_vgg_golden import VGG19, vgg_loss  # noqa: E402

ADAM_EPS = 1e-3
LR = 1e-3
NDF = 4
NUM_D = 3


class NLayerD(nn.Module):
    """pix2pixHD's NLayerDiscriminator (n_layers 3, getIntermFeat): sub-modules model0..model4."""

    def __init__(self, cin, ndf, n_layers=3):
        super().__init__()
        kw, padw = 4, 2  # padw = ceil((kw - 1) / 2)
        seq = [[nn.Conv2d(cin, ndf, kw, stride=2, padding=padw), nn.LeakyReLU(0.2)]]
        nf = ndf
        for _ in range(1, n_layers):
            prev, nf = nf, min(nf * 2, 512)
            seq += [[nn.Conv2d(prev, nf, kw, stride=2, padding=padw), nn.InstanceNorm2d(nf), nn.LeakyReLU(0.2)]]
        prev, nf = nf, min(nf * 2, 512)
        seq += [[nn.Conv2d(prev, nf, kw, stride=1, padding=padw), nn.InstanceNorm2d(nf), nn.LeakyReLU(0.2)]]
        seq += [[nn.Conv2d(nf, 1, kw, stride=1, padding=padw)]]
        for n, s in enumerate(seq):
            setattr(self, "model" + str(n), nn.Sequential(*s))
        self.n = len(seq)


class MultiscaleD(nn.Module):
    """pix2pixHD's MultiscaleDiscriminator(getIntermFeat=True): scale{i}_layer{j} sub-modules;
    scale{num_D-1} sees the full resolution, scale0 the coarsest."""

    def __init__(self, cin, ndf, num_d=3, n_layers=3):
        super().__init__()
        self.num_d, self.nl = num_d, n_layers + 2
        for i in range(num_d):
            d = NLayerD(cin, ndf, n_layers)
            for j in range(self.nl):
                setattr(self, "scale%d_layer%d" % (i, j), getattr(d, "model" + str(j)))
        self.down = nn.AvgPool2d(3, stride=2, padding=[1, 1], count_include_pad=False)

    def forward(self, x):
        out = []
        for i in range(self.num_d):
            res = [x]
            for j in range(self.nl):
                res.append(getattr(self, "scale%d_layer%d" % (self.num_d - 1 - i, j))(res[-1]))
            out.append(res[1:])
            if i != self.num_d - 1:
                x = self.down(x)
        return out


def lsgan(preds, real):
    return sum(F.mse_loss(p[-1], torch.full_like(p[-1], 1.0 if real else 0.0)) for p in preds)


def step(G, D, optG, optD, x, real, vgg=None):
    fake = G(x)
    pred_fake_pool = D(torch.cat((x, fake.detach()), 1))
    loss_d_fake = lsgan(pred_fake_pool, False)
    pred_real = D(torch.cat((x, real), 1))
    loss_d_real = lsgan(pred_real, True)
    pred_fake = D(torch.cat((x, fake), 1))
    loss_g_gan = lsgan(pred_fake, True)
    fm = 0
    for i in range(NUM_D):
        for j in range(len(pred_fake[i]) - 1):
            fm = fm + (1.0 / NUM_D) * (4.0 / (3 + 1)) * F.l1_loss(pred_fake[i][j], pred_real[i][j].detach())
    rec = F.l1_loss(fake, real)
    lv = vgg_loss(vgg, fake, real) if vgg is not None else torch.zeros(())
    loss_g = (lv if vgg is not None else rec) + loss_g_gan + 0.1 * fm
    loss_d = 0.5 * (loss_d_fake + loss_d_real)
    adam_steps(optG, loss_g, optD, loss_d)
    return [t.item() for t in (rec, loss_g_gan, fm, loss_d_fake, loss_d_real, lv)]


def adam_steps(optG, loss_g, optD, loss_d):
    """pix2pixHD's update order: G from loss_g, then D from loss_d."""
    optG.zero_grad()
    loss_g.backward()
    optG.step()
    optD.zero_grad()
    loss_d.backward()
    optD.step()


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--check":
        sd = {k: torch.from_numpy(v) for k, v in st_load(sys.argv[2]).items() if not k.startswith("optimizer.")}
        cin = sd["scale0_layer0.0.weight"].shape[1]
        ndf = sd["scale0_layer0.0.weight"].shape[0]
        num_d = len([k for k in sd if k.endswith("_layer0.0.weight")])
        D = MultiscaleD(cin, ndf, num_d)
        D.load_state_dict(sd, strict=True)
        print("OK: %s loads into MultiscaleDiscriminator(getIntermFeat=True) strictly: %d tensors, ndf %d, %d scales"
              % (sys.argv[2], len(sd), ndf, num_d))
        return 0
    torch.manual_seed(20210105)
    torch.set_num_threads(1)
    G = UNet(4)
    D = MultiscaleD(7, NDF, NUM_D)
    fp16_weights_random_bn(G)
    with torch.no_grad():
        for name, p in D.named_parameters():  # pix2pixHD: conv weights N(0, 0.02)
            if name.endswith("weight"):
                p.normal_(0.0, 0.02)
            p.copy_(p.half().float())
    gsd = []
    for name, t in G.state_dict().items():
        a = t.detach().numpy()
        if a.dtype == np.float32 and a.ndim == 4:
            a = a.astype(np.float16)
        gsd.append((name, a.copy()))
    st_save(os.path.join(HERE, "G.safetensors"), gsd, {"format": "pt"})
    st_save(os.path.join(HERE, "D.safetensors"), [(k, v.numpy().copy()) for k, v in D.state_dict().items()],
            {"format": "pt"})
    x = torch.rand(1, 4, 37, 53)
    real = torch.rand(1, 3, 37, 53)
    G0, D0 = copy.deepcopy(G), copy.deepcopy(D)
    for fname, use_vgg in (("step.safetensors", False), ("step_vgg.safetensors", True)):
        G, D = copy.deepcopy(G0), copy.deepcopy(D0)
        vgg = vgg64 = None
        if use_vgg:  # the small random VGG19 of ../vgg (stage 2 of the paper: L_VGG + L_GAN + 0.1 L_FM)
            vgg = VGG19(4)
            vgg.load_state_dict({k: torch.from_numpy(v) for k, v in
                                 st_load(os.path.join(HERE, "..", "vgg", "vgg_w4.safetensors")).items()
                                 if k.startswith("features.")}, strict=False)  # up to features.28
            vgg64 = copy.deepcopy(vgg).double()
        G64, D64 = copy.deepcopy(G).double(), copy.deepcopy(D).double()
        G.train(), G64.train()
        mk = lambda m: torch.optim.Adam(m.parameters(), lr=LR, betas=(0.9, 0.999), eps=ADAM_EPS)  # noqa: E731
        losses = step(G, D, mk(G), mk(D), x, real, vgg)
        step(G64, D64, mk(G64), mk(D64), x.double(), real.double(), vgg64)
        out = [("input", x.numpy().copy()), ("target", real.numpy().copy())]
        for n, v in zip(("rec", "gan", "fm", "d_fake", "d_real", "vgg"), losses):
            out.append(("loss." + n, np.array([v], dtype=np.float32)))
        for tag, m, m64 in (("G.", G, G64), ("D.", D, D64)):
            sd64 = dict(m64.named_parameters())
            for name, p in m.named_parameters():
                sampled("after." + tag, "aftersum." + tag, name, p, out)
                t64 = sd64[name].detach()
                spread = ((p.detach().double() - t64).abs().max() / t64.abs().max().clamp_min(1e-30)).item()
                out.append(("spread." + tag + name, np.array([spread], dtype=np.float32)))
        st_save(os.path.join(HERE, fname), out, {"format": "pt", "lr": repr(LR), "adam_eps": repr(ADAM_EPS)})
        print("%s: losses rec %.6f gan %.6f fm %.6f d_fake %.6f d_real %.6f vgg %.6f" % ((fname,) + tuple(losses)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
