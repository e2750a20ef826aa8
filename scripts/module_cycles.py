#!/usr/bin/env python3
"""Module cycles between sibling modules in each crate (a subtree's references to a sibling subtree)."""
import re, sys, pathlib, itertools
def modpath(src, p):
    rel = p.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("lib", "main", "mod"): parts = parts[:-1]
    return tuple(parts)
crates = [p for p in pathlib.Path(".").glob("crates/*/src")] + [p for p in pathlib.Path(".").glob("benches/*/src")] + [pathlib.Path("python/src")]
total = 0
for src in crates:
    if not src.exists(): continue
    files = {modpath(src, p): p for p in src.rglob("*.rs")}
    mods = set(files)
    # inline mods ignored (tests)
    deps = set()
    for m, p in files.items():
        text = p.read_text()
        text = re.sub(r'#\[cfg\(test\)\]\s*mod\s+\w+\s*\{.*', '', text, flags=re.S)  # drop trailing test mods
        text = re.sub(r'//.*', '', text)
        # expand `use` groups crudely: collect paths crate::a::b, super::a, self::a
        for mt in re.finditer(r'\b(crate|super|self)((?:::\w+)+)', text):
            head, rest = mt.group(1), mt.group(2).split("::")[1:]
            if head == "crate": base = ()
            elif head == "super":
                base = m[:-1] if p.stem not in ("mod",) else m[:-1]
                # chained super
                while rest and rest[0] == "super": base = base[:-1]; rest = rest[1:]
            else: base = m
            target = base
            for seg in rest:
                if target + (seg,) in mods: target = target + (seg,)
                else: break
            deps.add((m, target))
        # `use crate::x::{a, b}` groups
        for mt in re.finditer(r'\b(crate|super)((?:::\w+)*)::\{([^}]*)\}', text):
            head, pre = mt.group(1), mt.group(2).split("::")[1:]
            base = () if head == "crate" else m[:-1]
            for item in mt.group(3).split(","):
                segs = pre + [s for s in item.strip().split("::") if s]
                target = base
                for seg in segs:
                    if target + (seg,) in mods: target = target + (seg,)
                    else: break
                deps.add((m, target))
    # sibling-level graph
    edges = set()
    for a, b in deps:
        # find divergence point
        k = 0
        while k < min(len(a), len(b)) and a[k] == b[k]: k += 1
        if k < len(a) and k < len(b):
            edges.add((a[:k+1], b[:k+1]))
    # SCCs via simple reachability
    nodes = sorted({x for e in edges for x in e})
    adj = {n: set() for n in nodes}
    for a, b in edges: adj[a].add(b)
    def reach(s):
        seen, st = set(), [s]
        while st:
            x = st.pop()
            for y in adj[x]:
                if y not in seen: seen.add(y); st.append(y)
        return seen
    R = {n: reach(n) for n in nodes}
    done = set()
    for n in nodes:
        if n in done or n not in R[n]: continue
        scc = sorted(x for x in nodes if x in R[n] and n in R[x])
        done |= set(scc)
        total += 1
        print(src.parent.name, " <-> ".join("/".join(x) for x in scc))
print(total, "cycles")
