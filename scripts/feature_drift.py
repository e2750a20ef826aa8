#!/usr/bin/env python3
"""Which crates a second build would compile again instead of reusing what `cargo test` built.

cargo builds a crate once per distinct feature set (resolver 2 resolves features for the packages
a command selects), and a crate whose dependency was built twice is built twice itself. The test
suite builds the default members with their dev-dependencies (`cargo test`), then the Python wheel
(`-p fracid-python`, no dev-dependencies) in the same target directory and profile: every crate
listed here is compiled a second time for the wheel.

Usage (from the repository root):
    python3 scripts/feature_drift.py                     # the wheel against `cargo test`
    python3 scripts/feature_drift.py -p fracid           # any other selection (cargo tree args)
Exit status 1 when a crate of the numeric stack (nalgebra, faer, fracsim, ident, drive) would be
built twice.
"""
import re
import subprocess
import sys

STACK = ("nalgebra", "matrixmultiply", "faer", "gemm", "fracsim", "ident", "drive")


def tree(args):
    """(features by package, children by package) from `cargo tree --prefix depth`."""
    out = subprocess.run(
        ["cargo", "tree", "--prefix", "depth", "-f", "{p}|{f}"] + args,
        capture_output=True, text=True, check=True,
    ).stdout
    feats, children, stack = {}, {}, []
    for line in out.splitlines():
        m = re.match(r"(\d+)(.*)", line)
        if not m or "|" not in line:
            continue
        depth, rest = int(m.group(1)), m.group(2)
        pkg, f = rest.split("|", 1)
        pkg = re.sub(r" \(.*?\)", "", pkg.replace(" (*)", "")).strip()
        feats.setdefault(pkg, f.replace(" (*)", "").strip())
        stack = stack[:depth]
        if stack:
            children.setdefault(stack[-1], set()).add(pkg)
        stack.append(pkg)
    return feats, children


def main():
    other = sys.argv[1:] or ["-e", "normal,build", "-p", "fracid-python"]
    base, _ = tree([])  # what `cargo test` at the root resolves (default members, dev edges)
    feats, children = tree(other)
    rebuilt = {}

    def visit(p):
        if p not in rebuilt:
            rebuilt[p] = False  # cycles (none expected) end here
            r = base.get(p) != feats[p]
            for c in children.get(p, ()):
                r |= visit(c)
            rebuilt[p] = r
        return rebuilt[p]

    for p in feats:
        visit(p)
    # crates the test build has too, built a second time (the others are built once anyway)
    again = sorted(p for p in feats if rebuilt[p] and p in base)
    for p in again:
        why = f"  (features {base[p] or '-'} -> {feats[p] or '-'})" if base[p] != feats[p] else ""
        print(f"built again: {p}{why}")
    shared = sum(p in base for p in feats)
    print(f"{shared - len(again)} of the {shared} crates shared with `cargo test` reused")
    bad = [p for p in again if p.split(" ")[0] in STACK]
    if bad:
        print("the numeric stack is built twice:", ", ".join(bad), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
