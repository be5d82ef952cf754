#!/usr/bin/python3
"""Peer for bench_unet: the same milesial UNet (bilinear; tests/data/unet/make_unet_golden.py)
in PyTorch on the CPU, 1x4xHxW: eval forward (no_grad) and one training step (forward, L1,
backward, Adam), minimum over reps after a warm-up, with as many threads as cores.

    /usr/bin/python3 benchmarks/peer_unet_torch.py [--width W] [--size HxW] [--reps N] [--no-train]
"""
import argparse
import importlib.util
import os
import sys
import time

try:
    import torch
    import torch.nn.functional as F
except ImportError:
    sys.exit("peer_unet_torch.py: PyTorch not found (apt install python3-torch; run with /usr/bin/python3)")

here = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location("golden", os.path.join(here, "..", "tests", "data", "unet",
                                                                     "make_unet_golden.py"))
golden = importlib.util.module_from_spec(spec)
spec.loader.exec_module(golden)

ap = argparse.ArgumentParser()
ap.add_argument("--width", type=int, default=16)
ap.add_argument("--size", default="308x410")
ap.add_argument("--reps", type=int, default=3)
ap.add_argument("--no-train", action="store_true")
a = ap.parse_args()
h, w = (int(v) for v in a.size.split("x"))
torch.set_num_threads(os.cpu_count() or 1)
torch.manual_seed(0)
m = golden.UNet(a.width)
x = torch.rand(1, 4, h, w)
t = torch.rand(1, 3, h, w)
m.eval()
best = 1e30
with torch.no_grad():
    for r in range(a.reps + 1):
        t0 = time.perf_counter()
        m(x)
        dt = time.perf_counter() - t0
        if r:
            best = min(best, dt)
print("torch %s, %d threads: unet width %d, 1x4x%dx%d: eval forward %.3f s"
      % (torch.__version__, torch.get_num_threads(), a.width, h, w, best))
if not a.no_train:
    m.train()
    opt = torch.optim.Adam(m.parameters(), lr=1e-4)
    best = 1e30
    for r in range(a.reps + 1):
        t0 = time.perf_counter()
        opt.zero_grad()
        F.l1_loss(m(x), t).backward()
        opt.step()
        dt = time.perf_counter() - t0
        if r:
            best = min(best, dt)
    print("torch: unet width %d, 1x4x%dx%d: train step (fwd + L1 + bwd + Adam) %.3f s" % (a.width, h, w, best))
