"""Fit many drive records on a Dask cluster (end-of-line testing of a production line).

Each record is a CSV file with columns ``t,u,y`` (as ``fracid drive prbs`` or ``fracid sim``
write them). One task per record: read it, fit it with :func:`fracid.fit_time`, return a small
summary (plain Python types, so results travel between processes and machines). fracid's fits
release the GIL, so a worker with several threads runs several fits at once; a cluster of many
machines runs as many as it has cores. Nothing here is specific to fracid but the fit itself.

Usage::

    pip install "fracid[dask]"
    python docs/examples/dask_fleet.py RECORDS_DIR --workers 2           # a local cluster
    python docs/examples/dask_fleet.py RECORDS_DIR --scheduler tcp://host:8786
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any, Dict, Iterable, List

import numpy as np

import fracid


def read_record(path: str) -> Dict[str, np.ndarray]:
    """``t, u, y`` columns of a CSV record (header line, ``#`` comments allowed)."""
    with open(path, encoding="utf-8") as f:  # comments cut first: genfromtxt would take a
        lines = [ln.split("#", 1)[0].strip() for ln in f]  # leading comment for the header
    data = np.genfromtxt([ln for ln in lines if ln], delimiter=",", names=True)
    return {k: np.asarray(data[k], dtype=float) for k in ("t", "u", "y")}


def fit_record(path: str, **options: Any) -> Dict[str, Any]:
    """Fit one record; the summary row (the error instead when the fit fails: one bad record
    does not stop the others)."""
    row: Dict[str, Any] = {"file": os.fspath(path)}
    try:
        rec = read_record(path)
        dt = float(np.median(np.diff(rec["t"])))
        fit = fracid.fit_time(rec["u"], rec["y"], dt, **options)
        row.update(
            model=str(fit.model),
            values=dict(fit.values),
            fit_validation_percent=fit.validation.nrmse_percent if fit.validation else None,
            warnings=list(fit.warnings),
            error=None,
        )
    except (fracid.FracidError, OSError, ValueError) as e:
        row.update(model=None, values=None, fit_validation_percent=None, warnings=[], error=str(e))
    return row


def fit_records(client: Any, paths: Iterable[str], **options: Any) -> List[Dict[str, Any]]:
    """Fit every record on the cluster behind ``client`` (a ``dask.distributed.Client``); the
    rows in the order of ``paths``."""
    futures = client.map(fit_record, list(paths), pure=False, **options)
    return client.gather(futures)


def main(argv: List[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("records", help="a directory of *.csv records")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--structure", default="pmsm")
    ap.add_argument("-o", "--output", default="dask-summary.json")
    a = ap.parse_args(argv)
    from dask.distributed import Client, LocalCluster

    paths = sorted(str(p) for p in Path(a.records).glob("*.csv"))
    if not paths:
        print(f"no *.csv in {a.records}", file=sys.stderr)
        return 2
    if a.scheduler:
        client = Client(a.scheduler)
    else:
        client = Client(LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True))
    with client:
        rows = fit_records(client, paths, structure=a.structure)
    Path(a.output).write_text(json.dumps(rows, indent=2) + "\n")
    failed = [r["file"] for r in rows if r["error"]]
    print(f"{len(rows)} records, {len(failed)} failed; summary: {a.output}")
    for f in failed:
        print(f"failed: {f}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
