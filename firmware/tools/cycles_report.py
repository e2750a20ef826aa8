#!/usr/bin/env python3
"""Summarise firmware/tools/cycles.c's callgrind dumps (one dump per call) into worst-case
instruction counts per entry point and path, and an estimate of C28x cycles.

Usage: cycles_report.py BINARY DUMP_DIR RATE_HZ OCTETS_PER_SAMPLE

Only the instructions of fracfw's own functions (those defined in fw_codec.o and fw_engine.o, listed
in DUMP_DIR/fracfw.syms) are counted: the harness and the callgrind client requests are not.

The C28x estimate (assumptions, see firmware/README.md; override with the environment):
  cycles = K * (x86 instructions - 64-bit mul - div) + MUL64 * 64-bit mul + DIV64 * 64-bit div
           + DIV32 * 32-bit div
with K = C28X_K (default 2), MUL64 = C28X_MUL64 (40), DIV64 = C28X_DIV64 (1000),
DIV32 = C28X_DIV32 (100).
"""

from __future__ import annotations

import glob
import os
import re
import statistics
import subprocess
import sys

K = float(os.environ.get("C28X_K", "2"))
MUL64 = float(os.environ.get("C28X_MUL64", "40"))
DIV64 = float(os.environ.get("C28X_DIV64", "1000"))
DIV32 = float(os.environ.get("C28X_DIV32", "100"))
CLOCK_HZ = 150e6

REG64 = re.compile(r"%r(ax|bx|cx|dx|si|di|bp|sp|8|9|1[0-5])\b")


def classify(binary: str) -> dict[int, str]:
    """Address -> 'mul64', 'div64', 'div32' for the instructions that need a C28x penalty."""
    out = subprocess.run(
        ["objdump", "-d", "--no-show-raw-insn", binary], check=True, capture_output=True, text=True
    ).stdout
    kinds = {}
    for line in out.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(\S+)\s*(.*)", line)
        if not m:
            continue
        addr, mnem, ops = int(m.group(1), 16), m.group(2), m.group(3)
        wide = bool(REG64.search(ops)) or mnem.endswith("q")
        if mnem.startswith(("imul", "mul")) and wide:
            kinds[addr] = "mul64"
        elif mnem.startswith(("div", "idiv")):
            kinds[addr] = "div64" if wide else "div32"
    return kinds


def parse_dump(path: str, funcs: set[str], kinds: dict[int, str]):
    label, fn, skip = None, None, False
    ir = 0
    n = {"mul64": 0, "div64": 0, "div32": 0}
    with open(path) as f:
        for line in f:
            if line.startswith("desc: Trigger: Client Request: "):
                label = line[len("desc: Trigger: Client Request: "):].strip()
            elif line.startswith("fn="):
                fn = line[3:].strip()
            elif line.startswith("calls="):
                skip = True
            elif line.startswith("0x"):
                if skip:
                    skip = False
                    continue
                if fn in funcs:
                    parts = line.split()
                    addr, cost = int(parts[0], 16), int(parts[2])
                    ir += cost
                    k = kinds.get(addr)
                    if k:
                        n[k] += cost
    return label, ir, n


def c28x(ir: int, n: dict[str, int]) -> float:
    plain = ir - n["mul64"] - n["div64"] - n["div32"]
    return K * plain + MUL64 * n["mul64"] + DIV64 * n["div64"] + DIV32 * n["div32"]


def main() -> int:
    binary, dump_dir, rate_hz, octets = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    with open(os.path.join(dump_dir, "fracfw.syms")) as f:
        funcs = {line.strip() for line in f if line.strip()}
    kinds = classify(binary)
    rows: dict[str, list] = {}
    for path in glob.glob(os.path.join(dump_dir, "cg.out.*")):
        label, ir, n = parse_dump(path, funcs, kinds)
        if label is None:
            continue
        rows.setdefault(label, []).append((ir, n))
    if not rows:
        print("no dumps found", file=sys.stderr)
        return 1
    period = CLOCK_HZ / rate_hz
    print(f"### {rate_hz} Hz sample rate ({period:.0f} C28x cycles per sample at 150 MHz)\n")
    print("| entry:path | calls | median x86 instr | max x86 instr | 64-bit mul/div at max | C28x cycles at max (est.) |")
    print("|---|---:|---:|---:|---:|---:|")
    worst = {}
    for label in sorted(rows):
        vals = rows[label]
        irs = [v[0] for v in vals]
        top = max(vals, key=lambda v: c28x(*v))
        est = c28x(*top)
        entry = label.split(":")[0]
        if est >= worst.get(entry, (-1.0, ""))[0]:
            worst[entry] = (est, label)
        print(
            f"| {label} | {len(vals)} | {statistics.median(irs):.0f} | {max(irs)} | "
            f"{top[1]['mul64']}/{top[1]['div64'] + top[1]['div32']} | {est:.0f} |"
        )

    s_max = worst["sample"][0]
    rx_max = worst["rx"][0]
    tx_max = worst["tx"][0]
    s_path = worst["sample"][1]
    # mean load: every counted call of the scenarios (streamed runs with the line draining,
    # commands, keepalives) over the samples of the runs
    n_samples = sum(len(v) for label, v in rows.items() if label.startswith("sample:"))
    total = sum(c28x(*v) for vals in rows.values() for v in vals)
    mean = total / n_samples
    print()
    print(f"- sample interrupt, worst case: {s_max:.0f} cycles ({s_path}), "
          f"{100 * s_max / period:.1f} % of the period")
    print(f"- receive octet, worst case: {rx_max:.0f} cycles ({worst['rx'][1]}); transmit octet, "
          f"worst case: {tx_max:.0f} cycles ({worst['tx'][1]})")
    print(f"- mean load over the scenarios ({octets} octets per period each way): {mean:.0f} "
          f"cycles per sample, {100 * mean / period:.1f} % of the CPU")
    latency = max(rx_max, tx_max) + s_max
    print(f"- sample interrupt finished at the latest {latency:.0f} cycles after the timer fires "
          f"(one non-preemptible receive or masked transmit call at its worst, then the sample "
          f"interrupt at its worst): {100 * latency / period:.1f} % of the period")
    print(f"- model: K = {K:g}, MUL64 = {MUL64:g}, DIV64 = {DIV64:g}, DIV32 = {DIV32:g} cycles\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
