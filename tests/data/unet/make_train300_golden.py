#!/usr/bin/python3
"""Golden data for 300 training steps of the SMPLpix UNet (tests/test_nn_unet_train300.c).

Needs PyTorch (Debian: python3-torch, 1.13) and NumPy. Run with the system interpreter:

  /usr/bin/python3 tests/data/unet/make_train300_golden.py
      writes tests/data/unet/unet_w8_train300.safetensors (deterministic; commit it)

What the run is: the width-8 milesial UNet of make_unet_golden.py, from that golden file's initial
state, trained for STEPS Adam steps
(lr LR, betas 0.9/0.999, eps ADAM_EPS: why not 1e-8 is said in make_unet_golden.py) with the
mean L1 loss, in train mode (batch statistics), on two batches of two 4x45x67 images taken in
turn (even steps batch 0, odd steps batch 1). The inputs are smooth (bilinearly enlarged noise)
so that the task can be learnt; each target is a fixed random "teacher" 3x3 convolution of its
input through a sigmoid. The loss falls by about an order of magnitude over the run, so every
layer's gradient has to be right for the curve to follow PyTorch's.

The same run is repeated in float64: the difference between the float32 and float64 curves
(train.spread) is how far rounding alone moves a float32 run at each step, the yardstick for the
test's tolerance (long training amplifies any difference in summation order).

File contents (safetensors written by tools/spx_safetensors.py):
  * nothing of the model: it starts from the state_dict stored in unet_w8_golden.safetensors
    (make_unet_golden.py; conv weights exactly float16, batch-norm parameters and statistics
    away from their defaults), which the test loads with spx_unet_load;
  * train.input [2,2,4,45,67], train.target [2,2,3,45,67]: the two batches;
  * train.loss [STEPS]: the float32 loss before each step; train.loss64 [STEPS]: float64's;
  * train.eval_l1 [2]: the L1 loss of batch 0 through the trained model in eval mode (running
    statistics), float32 and float64;
  * train.after.<name> and train.spread.<name> for every running_mean / running_var: the float32
    statistics after the run and max |float32 - float64| / max |float64| of each.
Eval-mode outputs themselves are not compared: after 300 steps float32 and float64 disagree on
some pixels by a third of the output's range (a channel whose running variance is small), while
the loss over the whole batch stays within a percent.
"""
import os
import sys

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_unet_golden import ADAM_EPS, UNet, st_load, st_save  # noqa: E402

STEPS = 300
N, H, W = 2, 45, 67
LR = 3e-4


def smooth(gen, n, c):
    """n x c x H x W values in [0, 1], bilinearly enlarged from a 5x7 grid of uniform noise."""
    low = torch.rand(n, c, 5, 7, generator=gen)
    return F.interpolate(low, size=(H, W), mode="bilinear", align_corners=True)


def batches():
    gen = torch.Generator().manual_seed(300)
    teacher = (torch.rand(3, 4, 3, 3, generator=gen) - 0.5) * 1.5
    xs, ts = [], []
    for _ in range(2):
        x = smooth(gen, N, 4)
        xs.append(x)
        ts.append(torch.sigmoid(F.conv2d(x * 4 - 2, teacher, padding=1)))
    return torch.stack(xs), torch.stack(ts)


def train(model, xs, ts, dtype):
    model = model.to(dtype)
    model.train()
    opt = torch.optim.Adam(model.parameters(), lr=LR, betas=(0.9, 0.999), eps=ADAM_EPS)
    losses = []
    for step in range(STEPS):
        x, t = xs[step % 2].to(dtype), ts[step % 2].to(dtype)
        opt.zero_grad()
        loss = F.l1_loss(model(x), t)
        losses.append(loss.item())
        loss.backward()
        opt.step()
    model.eval()
    with torch.no_grad():
        eval_l1 = F.l1_loss(model(xs[0].to(dtype)), ts[0].to(dtype)).item()
    stats = {k: v for k, v in model.state_dict().items() if "running_" in k}
    return np.array(losses), eval_l1, stats


def main():
    torch.set_num_threads(1)
    here = os.path.dirname(os.path.abspath(__file__))
    init = st_load(os.path.join(here, "unet_w8_golden.safetensors"))
    state = {k: torch.from_numpy(v.astype(np.float32) if v.dtype == np.float16 else v)
             for k, v in init.items() if not k.startswith("golden.")}
    model, model64 = UNet(8), UNet(8)
    model.load_state_dict(state, strict=True)
    model64.load_state_dict(state, strict=True)
    out = []
    xs, ts = batches()
    loss32, eval32, stats32 = train(model, xs, ts, torch.float32)
    loss64, eval64, stats64 = train(model64, xs, ts, torch.float64)
    for k, v in stats32.items():
        out.append(("train.after." + k, v.numpy().copy()))
        spread = ((v.double() - stats64[k]).abs().max() / stats64[k].abs().max()).item()
        out.append(("train.spread." + k, np.array([spread], dtype=np.float32)))
    out += [
        ("train.input", xs.numpy().copy()),
        ("train.target", ts.numpy().copy()),
        ("train.loss", loss32.astype(np.float32)),
        ("train.loss64", loss64.astype(np.float32)),
        ("train.eval_l1", np.array([eval32, eval64], dtype=np.float32)),
    ]
    path = os.path.join(here, "unet_w8_train300.safetensors")
    st_save(path, out, {"format": "pt", "smplpix.golden": "unet w8, %d Adam steps, 2x2x4x%dx%d" % (STEPS, H, W),
                        "adam_eps": repr(ADAM_EPS)})
    rel = np.abs(loss32 - loss64) / loss64
    print("wrote", path)
    print("loss: first %.5f, step 100 %.5f, step 200 %.5f, last %.5f" % (loss32[0], loss32[100], loss32[200], loss32[-1]))
    print("float32 vs float64: loss rel diff max %.3g (last %.3g), eval L1 %.5f / %.5f" % (rel.max(), rel[-1], eval32, eval64))


if __name__ == "__main__":
    sys.exit(main())
