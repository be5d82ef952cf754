"""The UNet's FLOP count, shared by the Python peers of bench_unet (same convention as bench_unet)."""


def unet_gflop(wd, h, w):
    """2 x multiply-adds of every convolution of the width-wd UNet on one h x w input (as bench_unet)."""
    io = [(4, wd, wd), (wd, 2 * wd, 2 * wd), (2 * wd, 4 * wd, 4 * wd), (4 * wd, 8 * wd, 8 * wd),
          (8 * wd, 8 * wd, 8 * wd), (16 * wd, 8 * wd, 4 * wd), (8 * wd, 4 * wd, 2 * wd), (4 * wd, 2 * wd, wd),
          (2 * wd, wd, wd)]
    hs = [h >> i for i in range(5)]
    ws = [w >> i for i in range(5)]
    lvl = [0, 1, 2, 3, 4, 3, 2, 1, 0]
    f = 0.0
    for (a, b, c), l in zip(io, lvl):
        f += 2.0 * hs[l] * ws[l] * 9 * (a * b + b * c)
    f += 2.0 * h * w * wd * 3
    return f * 1e-9
