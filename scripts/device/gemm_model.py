#!/usr/bin/env python3
"""Static check and roofline / occupancy model of the GPU class's GEMM engine on an NVIDIA H200.

usage: scripts/device/gemm_model.py [--build DIR] [--batch N] [--sass FILE --ptxas FILE --opts FILE]

1. The sources and options the library builds for a GPU-class device (SPX_TUNE_CLASS=gpu; any
   SPX_TUNE_* in the environment applies) are dumped by `smplpix devices --warmup`
   (SPX_CL_DUMP_DIR), compiled by clang-15 for nvptx64-nvidia-nvcl with libclc's built-ins linked
   (libclc-15), assembled by NVIDIA's ptxas -arch=sm_90 -v and disassembled by nvdisasm.
   (Tools: $CLANG, $LIBCLC, $PTXAS, $NVDISASM; defaults clang-15, /usr/lib/clc/nvptx64--nvidiacl.bc,
   and the pinned ptxas / nvdisasm of scripts/device/nvidia_tools.sh.)
2. Per kernel: registers, spills, stack, shared memory, work-groups per SM (occupancy); fails (exit 1)
   on a spill or stack frame in a GEMM-engine kernel or registers over its budget (the `kernel`
   rows of scripts/device/gpu_kernels.txt, which make gpu-static checks for every program).
3. The inner loop (the backward branch enclosing the most FFMAs) of spx_gemm_conv and spx_gemm_dw:
   its FFMA share of the issued instructions.
4. Per UNet-64 layer at 308x410 (bench_conv2d's shapes): the forward, data-gradient and
   weight-gradient launches as the host makes them (lib/nn/conv2d_gemm.c: tiles, reduction splits,
   chunks), and the modelled time and share of the float32 peak.

The model (assumptions, written down so that a GPU run can refute them):
  - H200: 132 SMs x 4 schedulers, 128 fp32 lanes per SM at 1.98 GHz (66.9 TFLOP/s), 65536 registers,
    228 KiB shared memory (48 KiB per work-group in OpenCL), 64 warps and 32 work-groups per SM;
    HBM 4.8 TB/s, of which a streaming kernel gets 85%.
  - The main loop is issue-bound: a scheduler issues one warp instruction per cycle and the FFMAs
    of the loop are the useful ones, so a resident, never-stalled SM runs at peak x FFMA share.
    Latency hiding: each warp has TM x TN independent FFMAs per step and the loads of the next slice
    in flight; with w warps per scheduler the issue rate is min(1, w / 2) of that (2 warps cover the
    shared-memory latency between the software-pipelined steps and the barrier of each slice).
  - Prologue / epilogue: one slice's worth of global-load latency (~1.5 us) plus the epilogue's
    stores per work-group wave.
  - Work-group quantisation: the launch runs in ceil(groups / (132 x groups per SM)) waves, the last
    one partly empty; work of padded tiles (rows past Cout, pixels past the image, channels padded
    to a slice) is counted as work done.
  - Memory: the copies (padded input, the weight gradient's padded dy), the split / chunk partials
    (written and read once) and the kernel's compulsory traffic (input once per row tile, output
    once, weights once per work-group from L2) at 85% of HBM bandwidth, not overlapped with the
    compute (an upper bound on time).
  - L1 / L2 and shared-memory bandwidth are not limits: per FMA the loop reads (BM+BN)/(BM*BN)*4
    bytes from global memory (0.094 at 64x128: 3.1 TB/s at the full peak, mostly L1/L2 hits) and
    (TM+TN)/4 conflict-free 128-byte shared-memory wavefronts per warp per step (25% of that pipe).
"""
import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter

SMS, SCHED, LANES, CLOCK = 132, 4, 128, 1.98e9
PEAK = SMS * LANES * 2 * CLOCK  # flop/s
REGS, SMEM, MAXWARPS, MAXWG = 65536, 228 * 1024, 64, 32
HBM = 4.8e12 * 0.85
LAT_SLICE = 1.5e-6

# every convolution of the UNet at width 64 (benchmarks/bench_conv2d.c `unet`): name, cin, cout, h, w, k, pad
UNET64 = [
    ("inc1", 4, 64, 308, 410, 3, 1), ("inc2", 64, 64, 308, 410, 3, 1), ("d1a", 64, 128, 154, 205, 3, 1),
    ("d1b", 128, 128, 154, 205, 3, 1), ("d2a", 128, 256, 77, 102, 3, 1), ("d2b", 256, 256, 77, 102, 3, 1),
    ("d3a", 256, 512, 38, 51, 3, 1), ("d3b", 512, 512, 38, 51, 3, 1), ("d4a", 512, 512, 19, 25, 3, 1),
    ("d4b", 512, 512, 19, 25, 3, 1), ("u1a", 1024, 512, 38, 51, 3, 1), ("u1b", 512, 256, 38, 51, 3, 1),
    ("u2a", 512, 256, 77, 102, 3, 1), ("u2b", 256, 128, 77, 102, 3, 1), ("u3a", 256, 128, 154, 205, 3, 1),
    ("u3b", 128, 64, 154, 205, 3, 1), ("u4a", 128, 64, 308, 410, 3, 1), ("u4b", 64, 64, 308, 410, 3, 1),
    ("outc", 64, 3, 308, 410, 1, 0),
]
FULL_RES = ("inc1", "inc2", "u4a", "u4b", "outc")
ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))


def tool(env, name):
    """$env, else the pinned NVIDIA tool of scripts/device/nvidia_tools.sh, else `name` on PATH."""
    if os.environ.get(env):
        return os.environ[env]
    if name in ("ptxas", "nvdisasm"):
        r = subprocess.run(["sh", os.path.join(ROOT, "scripts", "device", "nvidia_tools.sh")], capture_output=True,
                           text=True)
        if r.returncode == 0 and os.path.exists(os.path.join(r.stdout.strip(), name)):
            return os.path.join(r.stdout.strip(), name)
    p = shutil.which(name)
    if not p:
        sys.exit(f"gemm_model: {name} not found (set ${env})")
    return p


def compile_gemm(build, tmp):
    """Dump the GPU class's programs, compile conv2d_gemm.cl and conv2d_thin.cl: (ptxas log, sass, opts)."""
    src = os.path.join(tmp, "src")
    os.makedirs(src)
    env = dict(os.environ, SPX_TUNE_CLASS="gpu", SPX_NO_CACHE="1", SPX_CL_DUMP_DIR=src)
    r = subprocess.run([os.path.join(build, "smplpix"), "devices", "--warmup", "--device", "cpu"], env=env,
                       capture_output=True, text=True)
    if r.returncode:
        sys.exit("gemm_model: smplpix devices --warmup failed:\n" + r.stdout + r.stderr)
    clang, libclc = tool("CLANG", "clang-15"), os.environ.get("LIBCLC", "/usr/lib/clc/nvptx64--nvidiacl.bc")
    ptxas, nvdisasm = tool("PTXAS", "ptxas"), tool("NVDISASM", "nvdisasm")
    logs, sass, opts = "", "", ""
    for prog in ("conv2d_gemm.cl", "conv2d_thin.cl"):
        o = open(os.path.join(src, prog + ".opts")).read().split()
        opts += " ".join(o) + "\n"
        base = os.path.join(tmp, prog)
        subprocess.run([clang, "-target", "nvptx64-nvidia-nvcl", "-x", "cl", *o, "-Xclang", "-finclude-default-header",
                        "-Xclang", "-cl-ext=-cl_khr_fp64,-cl_khr_fp16", "-Xclang", "-mlink-builtin-bitcode",
                        "-Xclang", libclc, "-Wno-linker-warnings", "-O2", "-S", "-o", base + ".ptx",
                        os.path.join(src, prog)], check=True)
        r = subprocess.run([ptxas, "-arch=sm_90", "-v", base + ".ptx", "-o", base + ".cubin"], capture_output=True,
                           text=True, check=True)
        logs += r.stdout + r.stderr
        sass += subprocess.run([nvdisasm, "-c", base + ".cubin"], capture_output=True, text=True, check=True).stdout
    show = subprocess.run([os.path.join(build, "smplpix"), "tune", "--show", "--device", "cpu"], env=env,
                          capture_output=True, text=True, check=True).stdout
    opts += " ".join("-D%s=%s" % m for m in re.findall(r"^(CONV_\w+)\s+(-?\d+)\s", show, re.M)) + "\n"
    return logs, sass, opts


def parse_ptxas(log):
    k, out = None, {}
    for line in log.splitlines():
        m = re.search(r"Compiling entry function '(\w+)'", line)
        if m:
            k = m.group(1)
            out[k] = {"regs": 0, "spill": 0, "stack": 0, "smem": 0}
            continue
        if not k:
            continue
        m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
        if m:
            out[k]["stack"], out[k]["spill"] = int(m.group(1)), int(m.group(2)) + int(m.group(3))
        m = re.search(r"Used (\d+) registers", line)
        if m:
            out[k]["regs"] = int(m.group(1))
            s = re.search(r"(\d+) bytes smem", line)
            out[k]["smem"] = int(s.group(1)) if s else 0
    return out


def loop_mix(sass, kernel):
    """The instruction mix of the backward branch of `kernel` that encloses the most FFMAs."""
    body = sass.split(".text." + kernel + ":", 1)
    if len(body) < 2:
        return None
    text = body[1].split("\n.text.", 1)[0]
    labels, ins = {}, []
    for line in text.splitlines():
        m = re.match(r"^(\.L_x_\d+):", line)
        if m:
            labels[m.group(1)] = len(ins)
            continue
        m = re.match(r"\s+/\*[0-9a-f]+\*/\s+(?:@!?U?P\w+\s+)?([A-Z][A-Z0-9]*)[^;]*;", line)
        if m:
            ins.append((m.group(1), line))
    best = None
    for i, (op, line) in enumerate(ins):
        m = re.search(r"\((\.L_x_\d+)\)", line) if op == "BRA" else None
        if m and labels.get(m.group(1), i + 1) <= i:
            loop = [o for o, _ in ins[labels[m.group(1)]:i + 1]]
            if best is None or loop.count("FFMA") > best.count("FFMA"):
                best = loop
    return Counter(best) if best else None


def groups_per_sm(regs, wg, smem):
    per_warp = math.ceil(max(regs, 1) / 8) * 8 * 32
    by_regs = REGS // (per_warp * math.ceil(wg / 32))
    by_smem = SMEM // (smem + 1024) if smem else MAXWG
    return max(0, min(by_regs, by_smem, MAXWARPS // math.ceil(wg / 32), MAXWG))


def tiles_of(opts):
    d = dict(re.findall(r"-D(CONV_\w+)=(\d+)", opts))
    g = {k: int(d[k]) for k in d}
    return g


def rup(a, b):
    return (a + b - 1) // b * b


def launch_time(fmas_padded, groups, gps, ffma_share, wg, extra_bytes):
    """Seconds of one launch: the compute of `groups` work-groups at `gps` per SM, plus memory."""
    warps_per_sched = gps * wg / 32 / SCHED
    rate = PEAK / 2 * ffma_share * min(1.0, warps_per_sched / 2)
    waves = math.ceil(groups / (gps * SMS))
    fill = groups / (waves * gps * SMS)
    return fmas_padded / rate / fill + waves * LAT_SLICE + extra_bytes / HBM


def model_layer(L, t, k_conv, k_dw, batch):
    name, cin, cout, h, w, k, pad = L
    bm, bn, ks, split, qc = t["CONV_GEMM_BM"], t["CONV_GEMM_BN"], t["CONV_GEMM_KS"], t["CONV_GEMM_SPLIT"], t["CONV_DW_QC"]
    wg = bm // t["CONV_GEMM_TM"] * (bn // t["CONV_GEMM_TN"])
    flop = 2.0 * batch * cout * cin * k * k * h * w
    res = {"flop": flop}
    for pas, (r, m) in (("fwd", (cin, cout)), ("data", (cout, cin))):
        if pas == "fwd" and k == 1 and cout <= t.get("CONV_THIN_MAXC", 0):
            by = 4.0 * batch * h * w * (cin + cout)  # the bandwidth kernel: read x once, write y
            res[pas] = by / HBM + LAT_SLICE
            continue
        rp, mp = rup(r, ks), rup(m, bm)
        direct = k == 1 and pad == 0 and rp == r
        wp = w if direct else w + k - 1
        ntile = math.ceil(h * wp / bn)
        groups1 = mp // bm * ntile * batch
        nsl = k * k * rp // ks
        splits = 1
        while groups1 * splits < split and nsl // (2 * splits) >= 4:
            splits *= 2
        spl = math.ceil(nsl / splits)
        splits = math.ceil(nsl / spl)
        fmas = float(mp) * ntile * bn * batch * k * k * rp
        copy = 0 if direct else 4.0 * batch * (r * h * w + rp * (h + k - 1) * wp)
        traffic = 4.0 * batch * (r * h * w * (mp // bm) + m * h * w * (1 if splits == 1 else 2 * splits))
        res[pas] = launch_time(fmas, groups1 * splits, k_conv["gps"], k_conv["share"], wg, copy + traffic)
    # weight gradient: M = cout, N = cin*k*k, K = pixels in chunks of qc
    wp = w + 2 * pad
    qd = h * wp
    nch = math.ceil(qd / qc)
    kdim = cin * k * k
    groups = math.ceil(cout / bm) * math.ceil(kdim / bn) * nch
    fmas = float(rup(cout, bm)) * rup(kdim, bn) * rup(qd, ks) * batch
    copies = 0 if (k == 1 and pad == 0) else 4.0 * batch * (cin * (h * w + (h + 2 * pad) * wp) + cout * (h * w + qd))
    parts = 8.0 * nch * cout * kdim
    traffic = 4.0 * batch * qd * (cin + cout) * math.ceil(cout / bm)
    res["dw"] = launch_time(fmas, groups, k_dw["gps"], k_dw["share"], wg, copies + parts + traffic)
    return res


def read_budgets():
    """kernel name -> (max registers, work-group) from the `kernel` rows of gpu_kernels.txt"""
    b = {}
    for line in open(os.path.join(ROOT, "scripts", "device", "gpu_kernels.txt")):
        f = line.split()
        if len(f) == 4 and f[0] == "kernel":
            b[f[1]] = (int(f[3]), int(f[2]))
    return b


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--batch", type=int, default=1)
    ap.add_argument("--ptxas"), ap.add_argument("--sass"), ap.add_argument("--opts", help="the options (-DNAME=value of the tunables)")
    a = ap.parse_args()
    if a.ptxas and a.sass and a.opts:
        log, sass, opts = (open(p).read() for p in (a.ptxas, a.sass, a.opts))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            log, sass, opts = compile_gemm(a.build, tmp)
    t = tiles_of(opts)
    wg = t["CONV_GEMM_BM"] // t["CONV_GEMM_TM"] * (t["CONV_GEMM_BN"] // t["CONV_GEMM_TN"])
    ks = parse_ptxas(log)
    budgets, fails = read_budgets(), 0
    print("tiles: BM %d BN %d TM %d TN %d KS %d (work-group %d), split below %d groups, dw chunk %d" % (
        t["CONV_GEMM_BM"], t["CONV_GEMM_BN"], t["CONV_GEMM_TM"], t["CONV_GEMM_TN"], t["CONV_GEMM_KS"], wg,
        t["CONV_GEMM_SPLIT"], t["CONV_DW_QC"]))
    print("| kernel | registers (budget) | spill B | stack B | shared B | work-group | groups/SM | occupancy | "
          "loop FFMA share |")
    print("|---|---|---|---|---|---|---|---|---|")
    info = {}
    for name, v in ks.items():
        bud, bwg = budgets.get(name, (None, 256))
        kwg = wg if name in ("spx_gemm_conv", "spx_gemm_dw") else bwg
        gps = groups_per_sm(v["regs"], kwg, v["smem"])
        mix = loop_mix(sass, name) if name in ("spx_gemm_conv", "spx_gemm_dw") else None
        share = mix["FFMA"] / sum(mix.values()) if mix else None
        info[name] = {"gps": gps, "share": share}
        bad = v["spill"] or v["stack"] or (bud is not None and v["regs"] > bud)
        fails += bool(bad)
        print("| %s | %d (%s) | %d | %d | %d | %d | %d | %.0f%% | %s |%s" % (
            name, v["regs"], bud if bud is not None else "-", v["spill"], v["stack"], v["smem"], kwg, gps,
            100.0 * gps * kwg / 32 / MAXWARPS, "%.1f%% of %d" % (100 * share, sum(mix.values())) if mix else "-",
            " OVER BUDGET / SPILL" if bad else ""))
    print("\nmodelled on an H200, batch %d (predicted, not measured; ms and share of the %.1f TFLOP/s float32 peak)"
          % (a.batch, PEAK / 1e12))
    print("| layer | GFLOP | fwd ms | fwd % | data ms | data % | weights ms | weights % |")
    print("|---|---|---|---|---|---|---|---|")
    tot = Counter()
    for L in UNET64:
        r = model_layer(L, t, info["spx_gemm_conv"], info["spx_gemm_dw"], a.batch)
        f = r["flop"]
        pct = lambda s: 100.0 * f / s / PEAK
        mark = " (full res.)" if L[0] in FULL_RES else ""
        print("| %s%s | %.2f | %.3f | %.0f | %.3f | %.0f | %.3f | %.0f |" % (
            L[0], mark, f / 1e9, 1e3 * r["fwd"], pct(r["fwd"]), 1e3 * r["data"], pct(r["data"]), 1e3 * r["dw"],
            pct(r["dw"])))
        tot["flop"] += f
        tot["fwd"] += r["fwd"]
        tot["train"] += r["fwd"] + r["dw"] + (r["data"] if L[0] != "inc1" else 0)
        tot["train_flop"] += f * (2 if L[0] == "inc1" else 3)
        if L[0] in FULL_RES and L[0] != "outc":
            tot["full_flop"] += 3 * f
            tot["full_t"] += r["fwd"] + r["data"] + r["dw"]
    print("\nconvolutions of an eval forward: %.2f ms (%.0f%% of peak); of a training step (forward, data gradients "
          "but inc1's, weight gradients): %.2f ms (%.0f%%); full-resolution 3x3 layers, all passes: %.0f%% of peak" % (
              1e3 * tot["fwd"], 100 * tot["flop"] / tot["fwd"] / PEAK, 1e3 * tot["train"],
              100 * tot["train_flop"] / tot["train"] / PEAK, 100 * tot["full_flop"] / tot["full_t"] / PEAK))
    if fails:
        print("gemm_model: %d kernels spill, keep a stack frame or exceed their register budget" % fails)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
