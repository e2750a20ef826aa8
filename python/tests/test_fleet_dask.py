"""Many records on a Dask cluster (docs/fleets.md, docs/examples/dask_fleet.py): a local cluster
of two workers gives exactly the models of a serial loop, and a bad record fails alone."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import fracid

REPO = Path(__file__).resolve().parents[2]  # python/tests -> the repository
# Skip only when Dask itself is missing (python/ci.sh installs it).
pytest.importorskip("dask")
distributed = pytest.importorskip("dask.distributed")

DT = 1e-4


def _example():
    path = REPO / "docs" / "examples" / "dask_fleet.py"
    spec = importlib.util.spec_from_file_location("dask_fleet", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _write_records(tmp_path, n):
    truth = fracid.FracTf.parse("6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)")
    u = fracid.prbs(dt=DT, order=7, clock=0.003, periods=2)
    y0 = truth.simulate(u, DT)
    t = np.arange(u.size) * DT
    paths = []
    for seed in range(n):
        rng = np.random.default_rng(seed)
        y = y0 * (1 + 0.05 * rng.standard_normal()) + 0.02 * y0.std() * rng.standard_normal(u.size)
        p = tmp_path / f"rec_{seed:03d}.csv"
        np.savetxt(p, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="")
        paths.append(str(p))
    return paths


def test_local_cluster_equals_serial_loop(tmp_path):
    ex = _example()
    paths = _write_records(tmp_path, 6)
    bad = tmp_path / "broken.csv"
    bad.write_text("t,u,y\n0,1,nan\n")
    paths.append(str(bad))
    opts = dict(structure="commensurate", offsets="none", fit_offset=False)
    serial = [ex.fit_record(p, **opts) for p in paths]
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        rows = ex.fit_records(client, paths, **opts)
    assert [r["file"] for r in rows] == paths
    for got, want in zip(rows, serial):
        assert got == want  # bit for bit: the same fits, whatever the worker
    assert all(r["error"] is None for r in rows[:-1])
    assert rows[-1]["error"] and rows[-1]["values"] is None
    # and the fits are right: K within 5 % of its record's true gain (6.77 times 1 +- 5 %)
    ks = [r["values"]["K"] for r in rows[:-1]]
    assert all(5.5 < k < 8.0 for k in ks), ks
