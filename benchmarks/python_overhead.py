#!/usr/bin/env python3
"""Projection of the shipped body (6,890 vertices, data/cameras/default.json, 410x308) from
Python: smplpix.project (device path and plain-C reference path) against the same calls from C
(bench_project_call, same vertices, colours and camera) and against a pure-numpy z-buffer with
the projection's contract, all in the same run. Rounds alternate C / Python / numpy so drift in
the machine's load hits every side alike; each number is the median of the rounds' medians.

Usage: python3 benchmarks/python_overhead.py [BUILD_DIR] [--runs N] [--rounds R]
(BUILD_DIR: the CMake build tree; its libsmplpix.so and benchmarks/bench_project_call are used
unless SMPLPIX_LIBRARY is set.)"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def zbuffer_numpy(pos, col, cam):
    """Pure numpy: (u', v', d) = K (R x + t) in float32; column floor(u'/d), row floor(v'/d);
    d <= 0 and outside dropped; nearest depth wins, ties -> smallest index; background 1."""
    R = cam.R.astype(np.float32)
    K = cam.K.astype(np.float32)
    p = pos @ R.T + cam.t.astype(np.float32)
    q = p @ K.T
    d = q[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(q[:, 0] / d)
        v = np.floor(q[:, 1] / d)
    ok = (d > 0) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
    idx = np.nonzero(ok)[0]
    pix = v[idx].astype(np.int64) * cam.width + u[idx].astype(np.int64)
    order = np.lexsort((idx, d[idx], pix))  # by pixel, then depth, then index
    pix_s = pix[order]
    first = np.ones(len(order), bool)
    first[1:] = pix_s[1:] != pix_s[:-1]
    win = idx[order[first]]
    img = np.ones((cam.height * cam.width, 4), np.float32)
    img[pix_s[first], :3] = col[win]
    img[pix_s[first], 3] = d[win]
    return img.reshape(cam.height, cam.width, 4)


def median_ms(fn, runs):
    for _ in range(20):
        fn()
    t = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(t))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("build", nargs="?", default=os.path.join(ROOT, "build"))
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    build = os.path.abspath(a.build)
    os.environ.setdefault("SMPLPIX_LIBRARY", os.path.join(build, "libsmplpix.so"))
    sys.path.insert(0, os.path.join(ROOT, "python"))
    import smplpix

    mesh = smplpix.read_mesh(os.path.join(ROOT, "data/body/human_woman.obj"))
    cam_path = os.path.join(ROOT, "data/cameras/default.json")
    cam = smplpix.Camera.load(cam_path)[0]
    col = np.random.default_rng(1).random(mesh.vertices.shape, dtype=np.float32)
    ctx = smplpix.Context()
    dev = smplpix.project(ctx, mesh.vertices, col, cam)[0, 0]
    ref = smplpix.project(ctx, mesh.vertices, col, cam, reference=True)[0, 0]
    npz = zbuffer_numpy(mesh.vertices, col, cam)
    same = np.mean(np.all(npz == dev, axis=2))
    assert np.array_equal(dev, ref)
    bench_c = os.path.join(build, "benchmarks", "bench_project_call")
    rows = {k: [] for k in ("c", "c_ref", "py", "py_ref", "np")}
    load0 = open("/proc/loadavg").read().split()[:3]
    with tempfile.TemporaryDirectory() as tmp:
        cpath = os.path.join(tmp, "col.npy")
        np.save(cpath, col)
        for _ in range(a.rounds):
            out = subprocess.run([bench_c, str(a.runs), os.path.join(ROOT, "data/body/human_woman.obj"), cam_path, cpath],
                                 capture_output=True, text=True, check=True).stdout.split("\n")
            rows["c"].append(float(out[0].split()[2]))
            rows["c_ref"].append(float(out[1].split()[2]))
            rows["py"].append(median_ms(lambda: smplpix.project(ctx, mesh.vertices, col, cam), a.runs))
            rows["py_ref"].append(median_ms(lambda: smplpix.project(ctx, mesh.vertices, col, cam, reference=True),
                                            a.runs))
            rows["np"].append(median_ms(lambda: zbuffer_numpy(mesh.vertices, col, cam), a.runs))
    load1 = open("/proc/loadavg").read().split()[:3]
    m = {k: float(np.median(v)) for k, v in rows.items()}
    info = ctx.device_info()
    print(f"device: {info['name']} ({info['platform']}); numpy {np.__version__}; python {sys.version.split()[0]}")
    print(f"load average before {' '.join(load0)}, after {' '.join(load1)}; {a.rounds} rounds x {a.runs} calls")
    print(f"numpy z-buffer equals smplpix.project on {100 * same:.2f}% of pixels")
    print()
    print("| 6,890 vertices, 410x308 | from C ms | from Python ms | Python overhead ms/call | numpy z-buffer ms | numpy / Python |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, c, p in (("device (`spx_project`)", "c", "py"), ("plain-C reference (`spx_project_ref`)", "c_ref", "py_ref")):
        print(f"| {name} | {m[c]:.3f} | {m[p]:.3f} | {m[p] - m[c]:+.3f} | {m['np']:.3f} | {m['np'] / m[p]:.1f}x |")
    ctx.close()


if __name__ == "__main__":
    main()
