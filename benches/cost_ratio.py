#!/usr/bin/env python3
"""The default's cost against the plain fit's (issue 47): CPU seconds (user + system of the whole
process, getrusage RUSAGE_CHILDREN) of `fracid time FILE --json` (the loop closed: structures
compared, the best diagnosed, the general structure when the named ones fit poorly) and of
`fracid time FILE --json --plain` (the named structure fitted once), best of RUNS each, and their
ratio, with each path's exit code and held-out NRMSE (percent) of the model the report leads with.

    python3 benches/cost_ratio.py FRACID [--runs 3] [--json OUT.json] [FILE|DIR ...]

Without FILEs: the 13 time records of data/ (benches/lib.rs TIME_RECORDS). A DIR stands for its
*.csv (a zoo run's OUT/cases). The last lines give the ratio's median and maximum, and for zoo
cases (NNNN_CLASS.csv) the ratio by class.
"""

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

def time_records():
    """The time records of data/: benches/lib.rs's TIME_RECORDS, read from that file (one list)."""
    with open(os.path.join(HERE, "lib.rs")) as f:
        text = f.read()
    body = text[text.index("pub const TIME_RECORDS"):]
    body = body[: body.index("];")]
    return re.findall(r'"([^"]+\.csv)"', body)


def cpu_children():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def once(fracid, path, plain):
    args = [fracid, "time", path, "--json", "--quiet"]
    if plain:
        args.append("--plain")
    c0 = cpu_children()
    p = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    cpu = cpu_children() - c0
    held = None
    try:
        rep = json.loads(p.stdout)
        fit = rep.get("fit") or {}
        part = fit.get("validation") or fit.get("estimation") or {}
        held = part.get("nrmse_percent")
    except (ValueError, AttributeError):
        pass
    return cpu, p.returncode, held


def measure(fracid, path, runs):
    out = {}
    for plain in (True, False):
        best = None
        for _ in range(runs):
            cpu, code, held = once(fracid, path, plain)
            if best is None or cpu < best[0]:
                best = (cpu, code, held)
        out["plain" if plain else "default"] = best
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("fracid")
    ap.add_argument("files", nargs="*")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", dest="json_out")
    a = ap.parse_args()
    files = []
    for f in a.files or [os.path.join(HERE, "..", "data", r) for r in time_records()]:
        if os.path.isdir(f):
            files += sorted(os.path.join(f, n) for n in os.listdir(f) if n.endswith(".csv"))
        else:
            files.append(f)
    rows = []
    print("| record | plain CPU s (exit, held-out %) | default CPU s (exit, held-out %) | ratio |")
    print("|---|---|---|---|")
    for f in files:
        m = measure(a.fracid, f, a.runs)
        (pc, pe, ph), (dc, de, dh) = m["plain"], m["default"]
        ratio = dc / pc if pc > 0 else float("inf")
        name = os.path.basename(f)
        fmt = lambda h: "-" if h is None else f"{h:.1f}"
        print(f"| {name} | {pc:.3f} ({pe}, {fmt(ph)}) | {dc:.3f} ({de}, {fmt(dh)}) | {ratio:.1f}x |",
              flush=True)
        rows.append(dict(file=name, plain_cpu_s=pc, plain_exit=pe, plain_held_out=ph,
                         default_cpu_s=dc, default_exit=de, default_held_out=dh, ratio=ratio))
    ratios = [r["ratio"] for r in rows]
    if ratios:
        print(f"\nratio median {statistics.median(ratios):.1f}x, max {max(ratios):.1f}x "
              f"({max(rows, key=lambda r: r['ratio'])['file']}), over 10x: "
              f"{sum(r > 10 for r in ratios)} of {len(ratios)}")
    by_class = {}
    for r in rows:
        stem = r["file"].rsplit(".", 1)[0]
        if "_" in stem and stem.split("_", 1)[0].isdigit():
            by_class.setdefault(stem.split("_", 1)[1], []).append(r["ratio"])
    if by_class:
        print("\n| class | cases | ratio median | ratio max | over 10x |")
        print("|---|---|---|---|---|")
        for c, rs in by_class.items():
            print(f"| {c} | {len(rs)} | {statistics.median(rs):.1f}x | {max(rs):.1f}x | "
                  f"{sum(x > 10 for x in rs)} |")
    if a.json_out:
        with open(a.json_out, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    sys.exit(main())
