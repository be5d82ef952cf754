#!/usr/bin/python3
"""Inference-engine peers for bench_unet's eval row: the PyTorch peer's UNet (the milesial UNet of
tests/data/unet/make_unet_golden.py, same width, torch.manual_seed(0)) exported to ONNX by this
script, then run by ONNX Runtime (CPU execution provider, all graph optimisations) and/or OpenVINO
(CPU, FP32 inference precision hint, latency hint), each with as many threads as the machine has
cores. Eval forward, batch N, minimum over reps after one warm-up.

Needs torch (for the export) and onnxruntime / openvino in the running interpreter; an engine that
cannot be imported is skipped with a message on stderr (exit 0). Prints the same machine-readable
ROW lines as bench_unet (impl=onnxruntime / impl=openvino; memory: peak RSS of this process, which
includes the interpreter, torch and the engine).

    python benchmarks/peer_unet_onnx.py [--width W] [--size HxW] [--reps N] [--eval-batch N]
                                        [--engines onnxruntime,openvino] [--onnx DIR] [--profile]

--profile: OpenVINO also lists its per-layer times of the last timed inference (its PERF_COUNT
profiling; the timed row then includes the counters' overhead), to set beside
`SPX_TAPE_PROFILE=2 bench_unet` or `bench_conv2d --w16`.
"""
import argparse
import importlib
import os
import resource
import sys
import time
import warnings

here = os.path.dirname(os.path.abspath(__file__))

ap = argparse.ArgumentParser()
ap.add_argument("--width", type=int, default=16)
ap.add_argument("--size", default="308x410")
ap.add_argument("--reps", type=int, default=3)
ap.add_argument("--eval-batch", type=int, default=1)
ap.add_argument("--engines", default="onnxruntime,openvino")
ap.add_argument("--onnx", default="out/bench", help="directory for the exported .onnx files")
ap.add_argument("--profile", action="store_true", help="OpenVINO: print per-layer times")
a = ap.parse_args()
a.reps = max(a.reps, 1)
h, w = (int(v) for v in a.size.split("x"))
threads = os.cpu_count() or 1

try:
    import numpy as np
    import torch
except ImportError as e:
    sys.exit("peer_unet_onnx.py: %s (needs numpy and torch for the export)" % e)

sys.path.insert(0, os.path.join(here, "..", "tests", "data", "unet"))
sys.dont_write_bytecode = True
import make_unet_golden as golden  # noqa: E402
import peer_unet_gflop as flops  # noqa: E402

os.makedirs(a.onnx, exist_ok=True)
path = os.path.join(a.onnx, "unet_w%d_%dx%dx%d.onnx" % (a.width, a.eval_batch, h, w))
if not os.path.exists(path):
    torch.manual_seed(0)
    m = golden.UNet(a.width).eval()
    x = torch.rand(a.eval_batch, 4, h, w)
    tmp = path + ".tmp"
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # torch 1.13's exporter warns about shape inference of constants
        torch.onnx.export(m, x, tmp, opset_version=13, input_names=["x"], output_names=["y"])
    os.replace(tmp, path)

gf = flops.unet_gflop(a.width, h, w) * a.eval_batch
x = np.random.default_rng(0).random((a.eval_batch, 4, h, w), dtype=np.float32)


def timed(run):
    best = 1e30
    for r in range(a.reps + 1):  # r == 0: warm-up
        t0 = time.perf_counter()
        run()
        dt = time.perf_counter() - t0
        if r:
            best = min(best, dt)
    return best


def row(impl, version, best):
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print("%s %s, %d threads: unet width %d, %dx4x%dx%d: eval forward %.3f s (%.1f GFLOP/s)"
          % (impl, version, threads, a.width, a.eval_batch, h, w, best, gf / best))
    print("ROW impl=%s mode=eval width=%d batch=%d h=%d w=%d reps=%d ms=%.3f gflop=%.3f gflops=%.3f "
          "mem_bytes=%d mem_kind=maxrss threads=%d version=%s"
          % (impl, a.width, a.eval_batch, h, w, a.reps, 1e3 * best, gf, gf / best, maxrss, threads, version),
          flush=True)


def engine(module, label):
    """The engine's Python module, or None (said on stderr) when it is not installed."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        print("peer_unet_onnx.py: %s skipped: %s" % (label, e), file=sys.stderr)
        return None


for eng in a.engines.split(","):
    if eng == "onnxruntime":
        ort = engine("onnxruntime", "ONNX Runtime")
        if ort is None:
            continue
        so = ort.SessionOptions()
        so.intra_op_num_threads = threads
        so.inter_op_num_threads = 1
        so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        sess = ort.InferenceSession(path, so, providers=["CPUExecutionProvider"])
        row("onnxruntime", ort.__version__, timed(lambda: sess.run(None, {"x": x})))
        del sess
    elif eng == "openvino":
        ov = engine("openvino", "OpenVINO")
        if ov is None:
            continue
        core = ov.Core()
        cfg = {"INFERENCE_NUM_THREADS": threads, "INFERENCE_PRECISION_HINT": "f32", "PERFORMANCE_HINT": "LATENCY"}
        if a.profile:
            cfg["PERF_COUNT"] = "YES"
        cm = core.compile_model(path, "CPU", cfg)
        req = cm.create_infer_request()
        row("openvino", ov.__version__.split("-")[0], timed(lambda: req.infer({0: x})))
        if a.profile:
            total = 0.0
            for p in req.profiling_info:
                us = p.real_time.total_seconds() * 1e6
                if us > 0:
                    total += us
                    print("  openvino layer %-44s %-12s %-24s %8.0f us" % (p.node_name[:44], p.node_type, p.exec_type, us))
            print("  openvino layers: %.0f us in all" % total)
        del req, cm
    else:
        sys.exit("peer_unet_onnx.py: unknown engine %r (onnxruntime, openvino)" % eng)
