#!/usr/bin/python3
"""Peer for bench_conv2d: the same UNet-64 convolution shapes (1 x Cin x H x W, 3x3 pad 1 or
1x1) timed in PyTorch on the CPU (oneDNN), with as many threads as cores. Prints ms and
GFLOP/s for forward (+ folded-BN affine + ReLU, like the fused kernel), backward-data and
backward-weights, minimum over reps.

    /usr/bin/python3 benchmarks/peer_conv_torch.py [reps] [--unet]

(Debian's python3-torch lives in /usr/bin/python3, not in a pyenv/venv interpreter.)"""
import os
import sys
import time

try:
    import torch
    import torch.nn.functional as F
except ImportError:
    sys.exit("peer_conv_torch.py: PyTorch not found (apt install python3-torch; run with /usr/bin/python3)")

SHAPES = [
    ("inc.conv1 4->64", 4, 64, 308, 410, 3, 1),
    ("inc.conv2 64->64", 64, 64, 308, 410, 3, 1),
    ("down1 128->128", 128, 128, 154, 205, 3, 1),
    ("down4 512->512", 512, 512, 19, 25, 3, 1),
    ("up4.conv1 128->64", 128, 64, 308, 410, 3, 1),
    ("outc 1x1 64->3", 64, 3, 308, 410, 1, 0),
]
UNET = [(4, 64, 308, 410), (64, 64, 308, 410), (64, 128, 154, 205), (128, 128, 154, 205),
        (128, 256, 77, 102), (256, 256, 77, 102), (256, 512, 38, 51), (512, 512, 38, 51),
        (512, 512, 19, 25), (512, 512, 19, 25), (1024, 512, 38, 51), (512, 256, 38, 51),
        (512, 256, 77, 102), (256, 128, 77, 102), (256, 128, 154, 205), (128, 64, 154, 205),
        (128, 64, 308, 410), (64, 64, 308, 410)]


CPU = []  # process CPU time (all threads) of each best rep: less sensitive to other load


def best_ms(fn, reps):
    fn()  # warm-up
    best, best_cpu = float("inf"), 0.0
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        t, c = (time.perf_counter() - t0) * 1e3, (time.process_time() - c0) * 1e3
        if t < best:
            best, best_cpu = t, c
    CPU.append(best_cpu)
    return best


def main():
    args = [a for a in sys.argv[1:] if a != "--unet"]
    reps = int(args[0]) if args else 3
    torch.set_num_threads(os.cpu_count() or 1)
    torch.set_grad_enabled(False)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, mkldnn {torch.backends.mkldnn.is_available()}")
    print(f"{'shape (1x, HxW)':22s} {'GFLOP':>9s} | {'fwd ms':>9s} {'GF/s':>7s} | {'bwd-x ms':>9s} {'GF/s':>7s}"
          f" | {'bwd-w ms':>9s} {'GF/s':>7s}")
    for name, cin, cout, h, w, k, pad in SHAPES:
        x = torch.full((1, cin, h, w), 0.5)
        wt = torch.full((cout, cin, k, k), 0.01)
        dy = torch.full((1, cout, h, w), 0.25)
        sc = torch.ones(cout).view(1, cout, 1, 1)
        gf = 2.0 * cout * h * w * cin * k * k * 1e-9
        fwd = best_ms(lambda: F.relu(F.conv2d(x, wt, None, 1, pad) * sc + sc), reps)
        bx = best_ms(lambda: torch.nn.grad.conv2d_input(x.shape, wt, dy, 1, pad), reps)
        bw = best_ms(lambda: torch.nn.grad.conv2d_weight(x, wt.shape, dy, 1, pad), reps)
        print(f"{name:18s} {h:3d}x{w:<3d} {gf:7.2f} | {fwd:9.1f} {gf / fwd * 1e3:7.1f} | {bx:9.1f} "
              f"{gf / bx * 1e3:7.1f} | {bw:9.1f} {gf / bw * 1e3:7.1f}", flush=True)
        if os.environ.get("SPX_BENCH_CPU"):
            print(f"   cpu ms: {CPU[-3]:.1f} {CPU[-2]:.1f} {CPU[-1]:.1f}")
    if "--unet" in sys.argv:
        tot = gtot = 0.0
        c0 = len(CPU)
        for cin, cout, h, w in UNET + [(64, 3, 308, 410)]:
            k = 1 if cout == 3 else 3
            x = torch.full((1, cin, h, w), 0.5)
            wt = torch.full((cout, cin, k, k), 0.01)
            ms = best_ms(lambda: F.conv2d(x, wt, None, 1, k // 2), reps)
            tot += ms
            if os.environ.get("SPX_BENCH_CPU"):
                print(f"  {cin:4d}->{cout:<4d} {h:3d}x{w:<3d} wall {ms:7.1f} ms cpu {CPU[-1]:7.1f} ms")
            gtot += 2.0 * cout * h * w * cin * k * k * 1e-9
        print(f"UNet-64 all {len(UNET) + 1} convs, eval forward: {tot:.1f} ms, {gtot:.1f} GFLOP, "
              f"{gtot / tot * 1e3:.1f} GFLOP/s (CPU {sum(CPU[c0:]):.1f} ms)")


if __name__ == "__main__":
    main()
