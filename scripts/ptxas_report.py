#!/usr/bin/env python3
"""Register use, spills and stack of the MPM CUDA kernels from `nvcc -Xptxas -v` output.

    scripts/ptxas_report.sh            # compiles the kernel files mpm/src/cuda/kernels/*.cu for sm_90 and prints the table
    python3 scripts/ptxas_report.py LOG  # the table of a saved ptxas log

One line per kernel instantiation: kernel, model (PT phase transition, FR frictional), shape
(lin, quad), boundary code (bnd), variant, registers, stack frame, spill stores / loads [bytes],
static shared memory [bytes]. Library kernels (cub) are left out.
"""
import re
import subprocess
import sys


def demangle(names):
    try:
        out = subprocess.run(["c++filt"], input="\n".join(names), capture_output=True, text=True, check=True).stdout
        return out.splitlines()
    except (OSError, subprocess.CalledProcessError):
        return names


def short(name):
    m = re.search(r"::(\w+_kernel)<(.*)>\(", name)
    if not m:
        m = re.search(r"(\w+_kernel)", name)
        return (m.group(1) if m else name[:60]), ""
    kernel, args = m.group(1), m.group(2)
    tags = []
    if "PhaseTransitionModel" in args:
        tags.append("PT")
    elif "FrictionalModel" in args:
        tags.append("FR")
    if "QuadraticShape" in args:
        tags.append("quad")
    elif "LinearShape" in args:
        tags.append("lin")
    tail = args.split(">")[-1]  # what follows the model/shape types: numbers and bools
    nums = re.findall(r"\b(true|false|\d+)\b", tail)
    if kernel == "p2g_kernel" and nums:
        tags.append({"0": "atomic", "1": "warp", "2": "tile"}.get(nums[-1], nums[-1]))
    elif kernel == "grid_kernel" and nums:
        tags.append("bnd" if nums[-1] == "true" else "nobnd")
    elif kernel in ("g2p_kernel", "constitutive_kernel") and len(nums) >= 2:
        tags.append("launch_bounds(%s,%s)" % (nums[-2], nums[-1]))
    return kernel, " ".join(tags)


def parse(text):
    rows, cur, props = [], None, None
    for line in text.splitlines():
        m = re.search(r"Compiling entry function '(\S+)'", line)
        if m:
            cur, props = m.group(1), ("0", "0", "0")
            continue
        m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
        if m and cur:
            props = m.groups()
            continue
        m = re.search(r"Used (\d+) registers(?:.*?(\d+) bytes smem)?", line)
        if m and cur:
            rows.append([cur, int(m.group(1)), props, int(m.group(2) or 0)])
            cur = None
    names = demangle([r[0] for r in rows])
    out = []
    for r, n in zip(rows, names):
        if "cub::" in n or "thrust::" in n:
            continue
        k, tags = short(n)
        out.append((k, tags, r[1], r[2], r[3]))
    return sorted(set(out))


def main():
    text = open(sys.argv[1]).read() if len(sys.argv) > 1 else sys.stdin.read()
    print("%-24s %-34s %5s %6s %14s %7s" % ("kernel", "instantiation", "regs", "stack", "spill st/ld", "smem"))
    for k, tags, regs, (stack, st, ld), smem in parse(text):
        print("%-24s %-34s %5d %6s %14s %7d" % (k, tags, regs, stack, st + "/" + ld, smem))


if __name__ == "__main__":
    main()
