#!/usr/bin/env python3
"""Issue 32: the diagnosis against the plain fit, two fracid binaries alternated run by run.

Usage: python3 benches/compare/diag_ab.py BEFORE AFTER RUNS FILE...
Prints one markdown row per FILE: plain / --diagnose wall time (best of RUNS; 2 for a file
named diag_ratio) and their ratio, for each binary."""
import subprocess,time,sys
# ab.py BASE FINAL runs FILE... : whole-process wall time of `fracid time FILE --json` and
# `... --diagnose`, the two binaries alternated run by run, best of `runs`.
A,B,runs=sys.argv[1],sys.argv[2],int(sys.argv[3])
for r in sys.argv[4:]:
    n = 2 if 'diag_ratio' in r else runs
    t={(b,d):[] for b in (A,B) for d in (False,True)}
    for i in range(n):
        for (b,d) in t:
            t0=time.perf_counter(); p=subprocess.run([b,'time',r,'--json']+(['--diagnose'] if d else []),capture_output=True); t[(b,d)].append(time.perf_counter()-t0)
    m={k:min(v)*1e3 for k,v in t.items()}
    print(f"| {r.split('/')[-1]} | {m[(A,False)]:.0f} / {m[(A,True)]:.0f} ms: {m[(A,True)]/m[(A,False)]:.1f}x | {m[(B,False)]:.0f} / {m[(B,True)]:.0f} ms: {m[(B,True)]/m[(B,False)]:.1f}x |", flush=True)
