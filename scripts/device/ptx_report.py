#!/usr/bin/env python3
"""Per-kernel figures of PTX programs as NVIDIA's own assembler sees them, for an sm_90 GPU
(H100 / H200): scripts/device/analyse_ptx.sh (PTX that NVIDIA's OpenCL driver returned) and
scripts/device/gpu_static.sh (`make gpu-static`: PTX that clang + libclc made here).

For every .ptx file: `ptxas -arch=sm_90 -v` (registers, stack frame, spill stores / loads, static
shared memory = OpenCL local memory, barriers), then `nvdisasm` of the cubin. Loops are the back
edges of nvdisasm's listing (a branch to a label at or before it, as ptxas lays out loops); the
innermost loops contain no other, and the one with the most FFMA is reported as the kernel's inner
loop: its instruction count (NOPs left out), FFMA share, shared (LDS/STS), global (LDG/STG) and
local (LDL/STL: stack or spills) accesses.

Theoretical occupancy at the kernel's work-group size, from the sm_90 limits of NVIDIA's CUDA C++
Programming Guide (technical specifications per compute capability) and its occupancy calculator:
64K 32-bit registers per SM, allocated per warp in units of 256, warps in groups of 4 (one per
scheduler); at most 64 warps and 32 blocks per SM; 228 KiB of shared memory per SM, allocated in
128-byte units, 1 KiB of it reserved per block. OpenCL on NVIDIA allows 48 KiB of local memory per
work-group.

The rules file (scripts/device/gpu_kernels.txt) names the hot kernels with their work-group size
and register budget, the kernels that must have no spill and no stack frame, and the waived
stack frames; --check fails (exit 1) on any breach, naming the kernel.
"""
import argparse
import concurrent.futures
import fnmatch
import os
import re
import subprocess
import sys

SM90 = {
    "regs_per_sm": 65536, "reg_unit": 256, "warp_gran": 4, "max_regs": 255,
    "max_warps": 64, "max_blocks": 32,
    "smem_per_sm": 233472, "smem_unit": 128, "smem_reserved": 1024,
}
LOCAL_MAX = 49152  # OpenCL local memory per work-group on NVIDIA


def ceil_to(x, unit):
    return -(-x // unit) * unit


def occupancy(regs, smem, wg, arch=SM90):
    """(resident warps / max warps, blocks per SM, what limits them) at work-group size wg."""
    warps = -(-wg // 32)
    if warps < 1 or wg > 1024 or regs > arch["max_regs"]:
        return 0.0, 0, "work-group"
    per_warp = ceil_to(max(regs, 1) * 32, arch["reg_unit"])
    warps_by_regs = arch["regs_per_sm"] // per_warp // arch["warp_gran"] * arch["warp_gran"]
    limits = {
        "registers": warps_by_regs // warps,
        "warps": arch["max_warps"] // warps,
        "blocks": arch["max_blocks"],
        "local memory": arch["smem_per_sm"] // (ceil_to(smem, arch["smem_unit"]) + arch["smem_reserved"]),
    }
    limiter = min(limits, key=lambda k: (limits[k], k != "warps"))
    blocks = limits[limiter]
    return blocks * warps / arch["max_warps"], blocks, limiter


def same_occupancy_regs(regs, smem, wg, arch=SM90):
    """The most registers a kernel may use and keep the occupancy `regs` gives it."""
    occ = occupancy(regs, smem, wg, arch)[0]
    r = regs
    while r < arch["max_regs"] and occupancy(r + 1, smem, wg, arch)[0] >= occ:
        r += 1
    return r


def parse_ptxas(text):
    """ptxas -v output -> {entry: {regs, stack, spill_st, spill_ld, smem, barriers}}."""
    out, props, entry, fn = {}, {}, None, None
    for line in text.splitlines():
        m = re.search(r"Compiling entry function '([^']+)'", line)
        if m:
            entry = m.group(1)
            out[entry] = {"regs": 0, "stack": 0, "spill_st": 0, "spill_ld": 0, "smem": 0, "barriers": 0}
            continue
        m = re.search(r"Function properties for (\S+)", line)
        if m:
            fn = m.group(1)
            continue
        m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
        if m and fn:
            props[fn] = tuple(int(g) for g in m.groups())
            if fn in out:
                out[fn]["stack"], out[fn]["spill_st"], out[fn]["spill_ld"] = props[fn]
            continue
        m = re.search(r"Used (\d+) registers", line)
        if m and entry:
            e = out[entry]
            e["regs"] = int(m.group(1))
            b = re.search(r"used (\d+) barriers", line)
            s = re.search(r"(\d+) bytes smem", line)
            e["barriers"] = int(b.group(1)) if b else 0
            e["smem"] = int(s.group(1)) if s else 0
    return out


INSN = re.compile(r"^\s*/\*([0-9a-f]+)\*/\s+(?:@!?U?P[0-9T]\s+)?([A-Z][A-Z0-9_]*)(\S*)(.*?);")
LABEL = re.compile(r"^(\.L_x_\d+):\s*$")
FUNC = re.compile(r"^\.text\.(\S+):\s*$")
TARGET = re.compile(r"`\((\.L_x_\d+)\)")


def parse_sass(text):
    """nvdisasm listing -> {function: (instructions [(addr, opcode, target label)], {label: addr})}."""
    funcs, cur, pending = {}, None, []
    for line in text.splitlines():
        m = FUNC.match(line)
        if m:
            cur = funcs.setdefault(m.group(1), ([], {}))
            pending = []
            continue
        if cur is None:
            continue
        m = LABEL.match(line)
        if m:
            pending.append(m.group(1))
            continue
        m = INSN.match(line)
        if m:
            addr = int(m.group(1), 16)
            for lab in pending:
                cur[1][lab] = addr
            pending = []
            t = TARGET.search(line) if m.group(2) in ("BRA", "BRX", "JMP") else None
            cur[0].append((addr, m.group(2), t.group(1) if t else None))
    return funcs


MIX = {
    "ffma": ("FFMA", "FFMA32I"),
    "fp": ("FADD", "FMUL", "FADD32I", "FMUL32I", "FMNMX", "FSETP", "FSEL", "MUFU", "FCHK", "FSET"),
    "lds": ("LDS", "LDSM"), "sts": ("STS",), "ldg": ("LDG",), "stg": ("STG",),
    "local": ("LDL", "STL"), "bar": ("BAR",),
}


def mix(insns):
    m = {k: 0 for k in MIX}
    n = 0
    for _, op, _ in insns:
        if op == "NOP":
            continue
        n += 1
        for k, ops in MIX.items():
            if op in ops:
                m[k] += 1
    m["n"] = n
    m["ffma_share"] = m["ffma"] / n if n else 0.0
    return m


def inner_loop(insns, labels):
    """The innermost loop (a back edge's [target, branch] span) with the most FFMA, as
    (mix, start, end); the whole kernel's mix with start = end = None when it has no loop."""
    loops = []
    for addr, _, lab in insns:
        if lab in labels and labels[lab] < addr:  # (a branch to itself is the trap after EXIT)
            loops.append((labels[lab], addr))
    inner = [l for l in loops if not any(o != l and l[0] <= o[0] and o[1] <= l[1] for o in loops)]
    best = None
    for a, b in set(inner):
        m = mix([i for i in insns if a <= i[0] <= b])
        if best is None or (m["ffma"], m["n"]) > (best[0]["ffma"], best[0]["n"]):
            best = (m, a, b)
    return best if best else (mix(insns), None, None)


def read_rules(path):
    """rules file -> {"kernel": {name: (wg, max_regs)}, "strict": [glob], "waive": {name: bytes}}."""
    rules = {"kernel": {}, "strict": [], "waive": {}}
    if not path:
        return rules
    with open(path) as f:
        for no, raw in enumerate(f, 1):
            w = raw.split("#", 1)[0].split()
            if not w:
                continue
            try:
                if w[0] == "kernel" and len(w) == 4:
                    rules["kernel"][w[1]] = (int(w[2]), int(w[3]))
                elif w[0] == "strict" and len(w) > 1:
                    rules["strict"] += w[1:]
                elif w[0] == "waive" and len(w) >= 4:
                    rules["waive"][w[1]] = int(w[2])
                else:
                    raise ValueError
            except ValueError:
                raise SystemExit("%s:%d: expected `kernel NAME WG REGS`, `strict GLOB...` or "
                                 "`waive NAME BYTES REASON`, not: %s" % (path, no, raw.strip()))
    return rules


def check(rows, rules, complete=True):
    """The breaches of the rules by the analysed kernels (rows: {kernel: row}), one line each;
    complete: rows are every program, so a rule naming no kernel is stale."""
    bad = []
    for k, r in sorted(rows.items()):
        if r["smem"] > LOCAL_MAX:
            bad.append("%s (%s): %d bytes of local memory, over NVIDIA's 48 KiB" % (k, r["program"], r["smem"]))
        if not any(fnmatch.fnmatchcase(k, g) for g in rules["strict"]):
            continue
        if r["spill_st"] or r["spill_ld"]:
            bad.append("%s (%s): spills (%d bytes stored, %d loaded)" % (k, r["program"], r["spill_st"], r["spill_ld"]))
        waived = rules["waive"].get(k, 0)
        if r["stack"] > waived:
            bad.append("%s (%s): a %d-byte stack frame%s" % (k, r["program"], r["stack"],
                                                            " (waived up to %d)" % waived if waived else ""))
    for k, allowed in sorted(rules["waive"].items()):
        if k not in rows:
            if complete:
                bad.append("waive %s: no analysed kernel has that name (remove the line)" % k)
        elif rows[k]["stack"] == 0:
            bad.append("waive %s: it has no stack frame now (remove the line)" % k)
    for k, (wg, budget) in sorted(rules["kernel"].items()):
        if k not in rows:
            if complete:
                bad.append("kernel %s: no analysed kernel has that name (rename or remove the row)" % k)
        elif rows[k]["regs"] > budget:
            bad.append("%s (%s): %d registers, over its budget of %d" % (k, rows[k]["program"], rows[k]["regs"], budget))
    return bad


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    return p.returncode, p.stdout


def assemble(ptx, work, ptxas, nvdisasm, arch):
    """ptxas + nvdisasm of one PTX file -> (program, {kernel: row}, note or None)."""
    prog = os.path.basename(ptx)[:-4]
    cubin, src = os.path.join(work, prog + ".cubin"), ptx
    rc, log = run([ptxas, "-arch=" + arch, "-v", "-o", cubin, src])
    note = None
    m = re.search(r"Unsupported \.version (\d+\.\d+); current version is '(\d+\.\d+)'", log)
    if rc and m:  # PTX newer than this ptxas: its instructions are older than the version line says
        with open(ptx) as f:
            text = re.sub(r"^\.version \d+\.\d+", ".version " + m.group(2), f.read(), count=1, flags=re.M)
        src = os.path.join(work, prog + ".v.ptx")
        with open(src, "w") as f:
            f.write(text)
        rc, log = run([ptxas, "-arch=" + arch, "-v", "-o", cubin, src])
        note = "%s: .version %s lowered to %s for this ptxas" % (prog, m.group(1), m.group(2))
    with open(os.path.join(work, prog + ".ptxas.log"), "w") as f:
        f.write(log)
    if rc:
        raise RuntimeError("%s: ptxas failed: %s" % (ptx, next((l for l in log.splitlines() if "error" in l.lower()),
                                                                 log.strip()[:300])))
    kernels = parse_ptxas(log)
    sass = {}
    if nvdisasm:
        rc, listing = run([nvdisasm, "-c", cubin])
        if rc:
            raise RuntimeError("%s: nvdisasm failed: %s" % (cubin, listing.strip()[:300]))
        with open(os.path.join(work, prog + ".sass"), "w") as f:
            f.write(listing)
        sass = parse_sass(listing)
    for k, r in kernels.items():
        r["program"] = prog
        insns, labels = sass.get(k, ([], {}))
        r["loop"], r["loop_start"], r["loop_end"] = inner_loop(insns, labels) if insns else (None, None, None)
    return prog, kernels, note


def fmt_row(k, r, rules, md):
    wg, budget = rules["kernel"].get(k, (0, 0))
    occ = "%.0f%% (%s)" % (100 * r["occ"][0], r["occ"][2]) if wg else "-"
    lp = r["loop"]
    if lp is None:
        loop = "-"
    else:
        where = "loop" if r["loop_start"] is not None else "no loop, whole kernel"
        loop = "%d instr, FFMA %.0f%%, LDS %d STS %d LDG %d STG %d LDL/STL %d (%s)" % (
            lp["n"], 100 * lp["ffma_share"], lp["lds"], lp["sts"], lp["ldg"], lp["stg"], lp["local"], where)
    regs, spills, stack = "%d%s" % (r["regs"], " / %d" % budget if budget else ""), "%d/%d" % (
        r["spill_st"], r["spill_ld"]), str(r["stack"])
    if "driver" in r:  # NVIDIA's driver's own figures (-cl-nv-verbose) beside ptxas's here
        d = r["driver"]
        regs += " (driver %d)" % d["regs"]
        spills += " (driver %d/%d)" % (d["spill_st"], d["spill_ld"])
        stack += " (driver %d)" % d["stack"]
    cells = [k, r["program"], str(wg) if wg else "-", regs, spills, stack, str(r["smem"]), occ, loop]
    if md:
        return "| " + " | ".join("`%s`" % c if i == 0 else c for i, c in enumerate(cells)) + " |"
    return "%-34s %-20s %5s %9s %7s %6s %6s %-24s %s" % tuple(cells)


def table(rows, shown, rules, md):
    if md:
        lines = ["| " + " | ".join(HEAD) + " |", "|" + "|".join("---" for _ in HEAD) + "|"]
    else:
        lines = ["%-34s %-20s %5s %9s %7s %6s %6s %-24s %s" % tuple(HEAD)]
    return "\n".join(lines + [fmt_row(k, rows[k], rules, md) for k in shown])


HEAD = ["kernel", "program", "WG", "regs / budget", "spills st/ld", "stack", "local B", "occupancy (limit)",
        "inner loop (innermost, most FFMA)"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("inputs", nargs="+", help=".ptx files or folders of them")
    ap.add_argument("--ptxas", default="ptxas")
    ap.add_argument("--nvdisasm", default="nvdisasm", help="'' to skip the instruction mix")
    ap.add_argument("--arch", default="sm_90")
    ap.add_argument("--rules", help="scripts/device/gpu_kernels.txt")
    ap.add_argument("--work", required=True, help="folder for the cubins, listings and ptxas logs")
    ap.add_argument("--all", action="store_true", help="a row for every kernel, not only the rules' hot ones")
    ap.add_argument("--markdown", action="store_true", help="the table as Markdown on stdout")
    ap.add_argument("--markdown-out", help="also write the table as Markdown to this file")
    ap.add_argument("--check", action="store_true",
                    help="the inputs are every program: exit 1 on a breach of the rules, stale rules included")
    ap.add_argument("--driver-log", action="append", default=[],
                    help="a build log of NVIDIA's driver with -cl-nv-verbose: its registers / spills beside ours")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    a = ap.parse_args(argv)
    rules = read_rules(a.rules)
    ptx = []
    for p in a.inputs:
        ptx += sorted(os.path.join(p, f) for f in os.listdir(p) if f.endswith(".ptx")) if os.path.isdir(p) else [p]
    if not ptx:
        print("ptx_report: no .ptx files in %s" % " ".join(a.inputs), file=sys.stderr)
        return 1
    os.makedirs(a.work, exist_ok=True)
    rows, notes = {}, []
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        futs = [ex.submit(assemble, p, a.work, a.ptxas, a.nvdisasm, a.arch) for p in ptx]
        for f in futs:
            try:
                _, kernels, note = f.result()
            except RuntimeError as e:
                print("ptx_report: %s" % e, file=sys.stderr)
                return 1
            rows.update(kernels)
            if note:
                notes.append(note)
    for path in a.driver_log:
        with open(path, errors="replace") as f:
            for k, d in parse_ptxas(f.read()).items():
                if k in rows:
                    rows[k]["driver"] = d
    for k, r in rows.items():
        wg = rules["kernel"].get(k, (0, 0))[0]
        r["occ"] = occupancy(r["regs"], r["smem"], wg) if wg else (0.0, 0, "-")
    shown = sorted(k for k in rows if a.all or k in rules["kernel"])
    print(table(rows, shown, rules, a.markdown))
    if a.markdown_out:
        with open(a.markdown_out, "w") as f:
            f.write(table(rows, shown, rules, True) + "\n")
    for n in notes:
        print("note: " + n)
    stack = ["%s (%d B)" % (k, r["stack"]) for k, r in sorted(rows.items()) if r["stack"]]
    print("%d kernels in %d programs; stack frames: %s" % (len(rows), len(ptx), ", ".join(stack) or "none"))
    bad = check(rows, rules, complete=a.check)
    for b in bad:
        print(("FAIL " if a.check else "over the rules: ") + b)
    return 1 if bad and a.check else 0


if __name__ == "__main__":
    sys.exit(main())
