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

With --device cuda (the GPU machine kit, scripts/device/run.sh) the model and data live on the
GPU, each timed pass ends with torch.cuda.synchronize(), the row reports
torch.cuda.max_memory_allocated (mem_kind=cuda_max_allocated) and --tf32 on|off sets
torch.backends.cuda.matmul.allow_tf32 and torch.backends.cudnn.allow_tf32 (default off: float32);
without torch or CUDA it exits 0 saying it skipped.

    /usr/bin/python3 benchmarks/peer_unet_torch.py [--width W] [--size HxW] [--reps N] [--batch N]
                                                  [--eval-batch N] [--no-train] [--no-eval]
                                                  [--device cpu|cuda] [--tf32 on|off]
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
    if cuda:
        mem, kind = torch.cuda.max_memory_allocated(), "cuda_max_allocated"
        torch.cuda.reset_peak_memory_stats()
    else:
        mem, kind = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, "maxrss"  # KiB on Linux
    print("ROW impl=%s mode=%s width=%d batch=%d h=%d w=%d reps=%d ms=%.3f gflop=%.3f gflops=%.3f "
          "mem_bytes=%d mem_kind=%s rss_before_bytes=%d threads=%d torch=%s"
          % (impl, mode, a.width, n, h, w, a.reps, 1e3 * best, gflop, gflop / best, mem, kind, before,
             torch.get_num_threads(), torch.__version__), flush=True)


def sync():
    if cuda:
        torch.cuda.synchronize()


ap = argparse.ArgumentParser()
ap.add_argument("--width", type=int, default=16)
ap.add_argument("--size", default="308x410")
ap.add_argument("--reps", type=int, default=3)
ap.add_argument("--batch", type=int, default=1)
ap.add_argument("--eval-batch", type=int, default=1)
ap.add_argument("--no-train", action="store_true")
ap.add_argument("--no-eval", action="store_true")
ap.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
ap.add_argument("--tf32", choices=("on", "off"), default="off")
a = ap.parse_args()
a.reps = max(a.reps, 1)
h, w = (int(v) for v in a.size.split("x"))
cuda = a.device == "cuda"
if cuda and not torch.cuda.is_available():
    print("peer_unet_torch.py: skipped: torch %s sees no CUDA device" % torch.__version__)
    sys.exit(0)
impl = "torch"
if cuda:
    torch.backends.cuda.matmul.allow_tf32 = a.tf32 == "on"
    torch.backends.cudnn.allow_tf32 = a.tf32 == "on"
    torch.backends.cudnn.benchmark = False
    impl = "torch_cuda_tf32" if a.tf32 == "on" else "torch_cuda"
dev = torch.device(a.device)
torch.set_num_threads(os.cpu_count() or 1)
torch.manual_seed(0)
m = golden.UNet(a.width).to(dev)
gf = unet_gflop(a.width, h, w)
if not a.no_eval:
    x = torch.rand(a.eval_batch, 4, h, w, device=dev)
    m.eval()
    before = rss_now()
    best = 1e30
    with torch.no_grad():
        for r in range(a.reps + 1):  # r == 0: warm-up
            sync()
            t0 = time.perf_counter()
            m(x)
            sync()
            dt = time.perf_counter() - t0
            if r:
                best = min(best, dt)
    print("%s %s, %d threads: unet width %d, %dx4x%dx%d: eval forward %.3f s (%.1f GFLOP/s)"
          % (impl, torch.__version__, torch.get_num_threads(), a.width, a.eval_batch, h, w, best,
             gf * a.eval_batch / best))
    row("eval", a.eval_batch, best, gf * a.eval_batch, before)
    del x
if not a.no_train:
    x = torch.rand(a.batch, 4, h, w, device=dev)
    t = torch.rand(a.batch, 3, h, w, device=dev)
    m.train()
    opt = torch.optim.Adam(m.parameters(), lr=1e-4)
    before = rss_now()
    best = 1e30
    for r in range(a.reps + 1):
        sync()
        t0 = time.perf_counter()
        opt.zero_grad()
        F.l1_loss(m(x), t).backward()
        opt.step()
        sync()
        dt = time.perf_counter() - t0
        if r:
            best = min(best, dt)
    print("%s %s, %d threads: unet width %d, %dx4x%dx%d: train step (fwd + L1 + bwd + Adam) %.3f s "
          "(~%.1f GFLOP/s at 3x forward flops)"
          % (impl, torch.__version__, torch.get_num_threads(), a.width, a.batch, h, w, best,
             3 * gf * a.batch / best))
    row("train", a.batch, best, 3 * gf * a.batch, before)
