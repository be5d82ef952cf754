#!/usr/bin/python3
"""Golden data for the SMPLpix UNet (tests/test_nn_unet.c) and a PyTorch-side checkpoint check.

Needs PyTorch (Debian: python3-torch, 1.13) and NumPy. Run with the system interpreter:

  /usr/bin/python3 tests/data/unet/make_unet_golden.py
      writes tests/data/unet/unet_w8_golden.safetensors (deterministic; commit it)

  /usr/bin/python3 tests/data/unet/make_unet_golden.py --check CKPT.safetensors IO.safetensors
      loads a checkpoint written by smplpix into the PyTorch model with
      load_state_dict(strict=True) (tensors named "optimizer.*" are the optimizer state and are
      set aside first), runs it on IO's "input" in eval mode and compares with IO's
      "eval_output" (what smplpix computed). test_nn_unet writes such a pair to
      build/test-tmp/test_nn_unet/{ours_ckpt,ours_io}.safetensors and prints this command.

  /usr/bin/python3 tests/data/unet/make_unet_golden.py --export OUT.safetensors [--width W]
      writes a freshly initialised PyTorch UNet state_dict (float32) as a checkpoint smplpix loads.

The model is the "milesial" UNet with bilinear upsampling, written out here so the tensor names
are exactly its state_dict names (inc.double_conv.0.weight, down1.maxpool_conv.1.double_conv.*,
up1.conv.double_conv.*, outc.conv.weight, ...).

Golden file contents (a safetensors file written by hand: 8-byte little-endian header length,
JSON header, raw little-endian data):
  * the model's state_dict at initialisation, under its own names, so the file is itself a
    PyTorch-written checkpoint. To stay small (< 1 MB) the initial conv weights are rounded to
    float16 before use and stored as F16 (so they are exact); everything else is F32, and
    num_batches_tracked is I64. BatchNorm gammas/betas/running stats are randomised (not 1/0)
    so that batch-norm folding and the affine gradients are really exercised.
  * golden.input [1,4,37,53], golden.target [1,3,37,53] (odd sizes: pads happen in up2, up4)
  * golden.output: train-mode forward with the initial weights; golden.loss: mean L1 to target
  * golden.grad.<param>: gradient of that loss for every parameter; tensors with more than
    SAMPLE elements are stored as a strided sample (flat indices k*stride, stride =
    ceil(numel/SAMPLE)) plus golden.gradsum.<param> = [sum g*r, sum |g|] over ALL elements,
    where r[i] = +1 if ((i*2654435761) mod 2^32) has bit 31 clear else -1 (float64 sums)
  * Adam (lr 1e-3, betas 0.9/0.999, eps ADAM_EPS = 1e-3), 3 steps, each a train-mode forward + backward
    on the same input/target: golden.losses [3] (loss before each step), then
    golden.after.<name>: every parameter (sampled like the gradients, with
    golden.aftersum.<param>) and every running_mean/running_var after the 3 steps,
    golden.after_nbt = num_batches_tracked (3)
  * golden.eval_output: eval-mode forward of the model after the 3 steps
  * golden.spread.<name> / golden.spread.eval_output: max |float32 - float64| / max |float64| of
    each tensor after the 3 steps, from the same run repeated in float64. Training amplifies
    rounding differences (steps 1 and 2 agree with float64 to ~1e-6, step 3 jumps to ~1e-4 in
    some layers, e.g. where a batch norm sees a channel of nearly constant values), so the test
    scales its tolerance for post-Adam tensors by this measured float32 spread.

Why eps = 1e-3 and not PyTorch's default 1e-8: with eps = 1e-8 an Adam step moves every weight by
about lr * sign(g), so weights whose gradient is at float32 noise level (here ~2e-5 of a tensor's
largest gradient; ours and PyTorch's are equally far from a float64 evaluation) move by +-lr at
random, and after 3 steps PyTorch float32 and PyTorch float64 themselves differ by ~5% of a
weight tensor's scale. With eps = 1e-3 the step is a smooth function of the gradient and float32
runs agree to ~1e-4, so the comparison can be tight. (The optimizer kernel's eps = 1e-8
behaviour is checked on its own against PyTorch in tests/test_nn_optim.c.)
"""
import argparse
import copy
import os
import sys

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

SAMPLE = 2048
ADAM_EPS = 1e-3


class DoubleConv(nn.Module):
    def __init__(self, cin, cout, mid=None):
        super().__init__()
        mid = mid or cout
        self.double_conv = nn.Sequential(
            nn.Conv2d(cin, mid, kernel_size=3, padding=1, bias=False),
            nn.BatchNorm2d(mid),
            nn.ReLU(inplace=True),
            nn.Conv2d(mid, cout, kernel_size=3, padding=1, bias=False),
            nn.BatchNorm2d(cout),
            nn.ReLU(inplace=True),
        )

    def forward(self, x):
        return self.double_conv(x)


class Down(nn.Module):
    def __init__(self, cin, cout):
        super().__init__()
        self.maxpool_conv = nn.Sequential(nn.MaxPool2d(2), DoubleConv(cin, cout))

    def forward(self, x):
        return self.maxpool_conv(x)


class Up(nn.Module):
    def __init__(self, cin, cout):
        super().__init__()
        self.up = nn.Upsample(scale_factor=2, mode="bilinear", align_corners=True)
        self.conv = DoubleConv(cin, cout, cin // 2)

    def forward(self, x1, x2):
        x1 = self.up(x1)
        dy = x2.size(2) - x1.size(2)
        dx = x2.size(3) - x1.size(3)
        x1 = F.pad(x1, [dx // 2, dx - dx // 2, dy // 2, dy - dy // 2])
        return self.conv(torch.cat([x2, x1], dim=1))


class OutConv(nn.Module):
    def __init__(self, cin, cout):
        super().__init__()
        self.conv = nn.Conv2d(cin, cout, kernel_size=1)

    def forward(self, x):
        return self.conv(x)


class UNet(nn.Module):
    def __init__(self, w=64, cin=4, cout=3):
        super().__init__()
        self.inc = DoubleConv(cin, w)
        self.down1 = Down(w, 2 * w)
        self.down2 = Down(2 * w, 4 * w)
        self.down3 = Down(4 * w, 8 * w)
        self.down4 = Down(8 * w, 16 * w // 2)
        self.up1 = Up(16 * w, 8 * w // 2)
        self.up2 = Up(8 * w, 4 * w // 2)
        self.up3 = Up(4 * w, 2 * w // 2)
        self.up4 = Up(2 * w, w)
        self.outc = OutConv(w, cout)

    def forward(self, x):
        x1 = self.inc(x)
        x2 = self.down1(x1)
        x3 = self.down2(x2)
        x4 = self.down3(x3)
        x5 = self.down4(x4)
        x = self.up1(x5, x4)
        x = self.up2(x, x3)
        x = self.up3(x, x2)
        x = self.up4(x, x1)
        return self.outc(x)


# ---------------------------------------------------------------- safetensors by hand (tools/spx_safetensors.py)
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tools"))
from spx_safetensors import DTYPES, NP_OF, st_load, st_save  # noqa: E402,F401 (re-exported to the other goldens)


def fp16_weights_random_bn(model):
    """Conv weights made exactly representable in float16; batch-norm affine parameters and running
    statistics drawn away from their defaults (torch's RNG, in module order)."""
    with torch.no_grad():
        for name, p in model.named_parameters():
            if name.endswith("weight") and p.dim() == 4:
                p.copy_(p.half().float())  # exactly representable in float16
        for m in model.modules():
            if isinstance(m, nn.BatchNorm2d):
                c = m.num_features
                m.weight.copy_(torch.rand(c) + 0.5)
                m.bias.copy_(torch.rand(c) * 0.2 - 0.1)
                m.running_mean.copy_(torch.rand(c) * 0.2 - 0.1)
                m.running_var.copy_(torch.rand(c) + 0.5)


def rsign(n):
    i = np.arange(n, dtype=np.uint64)
    h = (i * np.uint64(2654435761)) & np.uint64(0xFFFFFFFF)
    return np.where(h & np.uint64(0x80000000), -1.0, 1.0)


def sampled(prefix, sumprefix, name, t, out):
    a = t.detach().numpy().astype(np.float32).reshape(-1)
    n = a.size
    if n <= SAMPLE:
        out.append((prefix + name, a.reshape(t.shape)))
        return
    stride = (n + SAMPLE - 1) // SAMPLE
    out.append((prefix + name, a[::stride].copy()))
    d = a.astype(np.float64)
    out.append((sumprefix + name, np.array([np.dot(d, rsign(n)), np.abs(d).sum()], dtype=np.float32)))


def make_golden(path):
    torch.manual_seed(20210105)
    np.random.seed(20210105)
    torch.set_num_threads(1)
    model = UNet(8)
    fp16_weights_random_bn(model)
    out = []
    for name, t in model.state_dict().items():
        a = t.detach().numpy()
        if a.dtype == np.float32 and a.ndim == 4:
            a = a.astype(np.float16)
        out.append((name, a.copy()))

    x = torch.rand(1, 4, 37, 53)
    target = torch.rand(1, 3, 37, 53)
    out.append(("golden.input", x.numpy().copy()))
    out.append(("golden.target", target.numpy().copy()))

    # the same run in float64: how far float32 itself strays after the 3 steps (golden.spread.*)
    model64 = copy.deepcopy(model).double()
    model64.train()
    opt64 = torch.optim.Adam(model64.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=ADAM_EPS)
    for step in range(3):
        opt64.zero_grad()
        F.l1_loss(model64(x.double()), target.double()).backward()
        opt64.step()

    opt = torch.optim.Adam(model.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=ADAM_EPS)
    model.train()
    losses = []
    for step in range(3):
        opt.zero_grad()
        y = model(x)
        loss = F.l1_loss(y, target)
        losses.append(loss.item())
        loss.backward()
        if step == 0:
            out.append(("golden.output", y.detach().numpy().copy()))
            out.append(("golden.loss", np.array([loss.item()], dtype=np.float32)))
            for name, p in model.named_parameters():
                sampled("golden.grad.", "golden.gradsum.", name, p.grad, out)
        opt.step()
    out.append(("golden.losses", np.array(losses, dtype=np.float32)))
    for name, t in model.state_dict().items():
        if name.endswith("num_batches_tracked"):
            continue
        sampled("golden.after.", "golden.aftersum.", name, t, out)
        t64 = model64.state_dict()[name]
        spread = ((t.double() - t64).abs().max() / t64.abs().max().clamp_min(1e-30)).item()
        out.append(("golden.spread." + name, np.array([spread], dtype=np.float32)))
    out.append(("golden.after_nbt", np.array([3], dtype=np.int64)))
    model.eval()
    model64.eval()
    with torch.no_grad():
        y = model(x)
        y64 = model64(x.double())
        out.append(("golden.eval_output", y.numpy().copy()))
        spread = ((y.double() - y64).abs().max() / y64.abs().max()).item()
        out.append(("golden.spread.eval_output", np.array([spread], dtype=np.float32)))
    st_save(path, out, {"format": "pt", "smplpix.golden": "unet w8 1x4x37x53", "sample": str(SAMPLE), "adam_eps": repr(ADAM_EPS)})
    print("wrote", path, "losses", losses)


def check(ckpt_path, io_path, tol):
    sd = st_load(ckpt_path)
    opt = {k: v for k, v in sd.items() if k.startswith("optimizer.")}
    sd = {k: torch.from_numpy(v.astype(np.float32) if v.dtype == np.float16 else v)
          for k, v in sd.items() if not k.startswith("optimizer.")}
    w = sd["inc.double_conv.0.weight"].shape[0]
    model = UNet(w)
    model.load_state_dict(sd, strict=True)
    model.eval()
    io = st_load(io_path)
    x = torch.from_numpy(io["input"])
    with torch.no_grad():
        y = model(x).numpy()
    ours = io["eval_output"]
    if "sigmoid" in io and io["sigmoid"].reshape(-1)[0]:
        y = 1.0 / (1.0 + np.exp(-y))
    err = np.abs(y - ours).max() / max(np.abs(y).max(), 1e-6)
    print("checkpoint %s: width %d, %d tensors (+%d optimizer), eval output max rel err %.3g"
          % (ckpt_path, w, len(sd), len(opt), err))
    if not err <= tol:
        print("MISMATCH")
        return 1
    print("OK: PyTorch loads the smplpix checkpoint (strict) and reproduces its output")
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=None)
    ap.add_argument("--check", nargs=2, metavar=("CKPT", "IO"))
    ap.add_argument("--tol", type=float, default=1e-4)
    ap.add_argument("--export", metavar="OUT")
    ap.add_argument("--width", type=int, default=8)
    a = ap.parse_args()
    if a.check:
        return check(a.check[0], a.check[1], a.tol)
    if a.export:
        torch.manual_seed(0)
        m = UNet(a.width)
        st_save(a.export, [(k, v.numpy().copy()) for k, v in m.state_dict().items()], {"format": "pt"})
        return 0
    path = a.out or os.path.join(os.path.dirname(os.path.abspath(__file__)), "unet_w8_golden.safetensors")
    make_golden(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
