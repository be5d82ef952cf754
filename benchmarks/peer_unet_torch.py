#!/usr/bin/python3
"""Peer for bench_unet: the same milesial UNet (bilinear; tests/data/unet/make_unet_golden.py)
in PyTorch on the CPU, Nx4xHxW: eval forward (no_grad, eval mode) and one training step (zero_grad,
forward, L1, backward, Adam), minimum over reps after one warm-up, with
torch.set_num_threads(os.cpu_count()).

Prints the same machine-readable ROW lines as bench_unet (same GFLOP convention: 2 x conv
multiply-adds x batch for the forward, 3x that for a training step). Memory: there is no device
here, so the CPU analogue is reported: the process's peak resident set size
(resource.getrusage(RUSAGE_SELF).ru_maxrss, mem_kind=maxrss) after the row. It includes the
Python interpreter and the torch libraries; rss_before_bytes is the resident size just before the
row's first pass, for reference. Run one row per process for a per-row figure.

    /usr/bin/python3 benchmarks/peer_unet_torch.py [--width W] [--size HxW] [--reps N] [--batch N]
                                                  [--eval-batch N] [--no-train] [--no-eval]
"""
import argparse
import os
import resource
import sys
import time

try:
    import torch
    import torch.nn.functional as F
except ImportError:
    sys.exit("peer_unet_torch.py: PyTorch not found (apt install python3-torch; run with /usr/bin/python3)")

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "tests", "data", "unet"))
sys.dont_write_bytecode = True
import make_unet_golden as golden  # noqa: E402
from peer_unet_gflop import unet_gflop  # noqa: E402


def rss_now():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def row(mode, n, best, gflop, before):
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # KiB on Linux
    print("ROW impl=torch mode=%s width=%d batch=%d h=%d w=%d reps=%d ms=%.3f gflop=%.3f gflops=%.3f "
          "mem_bytes=%d mem_kind=maxrss rss_before_bytes=%d threads=%d torch=%s"
          % (mode, a.width, n, h, w, a.reps, 1e3 * best, gflop, gflop / best, maxrss, before,
             torch.get_num_threads(), torch.__version__), flush=True)


ap = argparse.ArgumentParser()
ap.add_argument("--width", type=int, default=16)
ap.add_argument("--size", default="308x410")
ap.add_argument("--reps", type=int, default=3)
ap.add_argument("--batch", type=int, default=1)
ap.add_argument("--eval-batch", type=int, default=1)
ap.add_argument("--no-train", action="store_true")
ap.add_argument("--no-eval", action="store_true")
a = ap.parse_args()
a.reps = max(a.reps, 1)
h, w = (int(v) for v in a.size.split("x"))
torch.set_num_threads(os.cpu_count() or 1)
torch.manual_seed(0)
m = golden.UNet(a.width)
gf = unet_gflop(a.width, h, w)
if not a.no_eval:
    x = torch.rand(a.eval_batch, 4, h, w)
    m.eval()
    before = rss_now()
    best = 1e30
    with torch.no_grad():
        for r in range(a.reps + 1):  # r == 0: warm-up
            t0 = time.perf_counter()
            m(x)
            dt = time.perf_counter() - t0
            if r:
                best = min(best, dt)
    print("torch %s, %d threads: unet width %d, %dx4x%dx%d: eval forward %.3f s (%.1f GFLOP/s)"
          % (torch.__version__, torch.get_num_threads(), a.width, a.eval_batch, h, w, best, gf * a.eval_batch / best))
    row("eval", a.eval_batch, best, gf * a.eval_batch, before)
    del x
if not a.no_train:
    x = torch.rand(a.batch, 4, h, w)
    t = torch.rand(a.batch, 3, h, w)
    m.train()
    opt = torch.optim.Adam(m.parameters(), lr=1e-4)
    before = rss_now()
    best = 1e30
    for r in range(a.reps + 1):
        t0 = time.perf_counter()
        opt.zero_grad()
        F.l1_loss(m(x), t).backward()
        opt.step()
        dt = time.perf_counter() - t0
        if r:
            best = min(best, dt)
    print("torch %s, %d threads: unet width %d, %dx4x%dx%d: train step (fwd + L1 + bwd + Adam) %.3f s "
          "(~%.1f GFLOP/s at 3x forward flops)"
          % (torch.__version__, torch.get_num_threads(), a.width, a.batch, h, w, best, 3 * gf * a.batch / best))
    row("train", a.batch, best, 3 * gf * a.batch, before)
