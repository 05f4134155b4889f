"""The dataset read unchanged by a distributed engine: Dask on a local cluster (worker processes on local
ports, started here) gets the counts DuckDB gets (`sniffer query`)."""

from __future__ import annotations

import datetime as dt
import shutil
from pathlib import Path

import pytest

from sniffer.cli import main

pytest.importorskip("dask.dataframe", reason="dask[dataframe,distributed] is in the test extra: pip install -e .[test]")
pytest.importorskip("distributed", reason="dask[distributed] is in the test extra")

CAPTURES = Path(__file__).resolve().parent.parent / "captures"


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Three captures on two links."""
    root = tmp_path_factory.mktemp("fleet")
    src = root / "in"
    src.mkdir()
    for name in ("a510", "errors", "tds-v8"):
        shutil.copy(CAPTURES / "sim" / f"{name}.mcap", src / f"{name}.mcap")
    ds = root / "ds"
    assert main(["export", str(src / "a510.mcap"), "--to", "dataset", str(ds), "--link", "drives"]) == 0
    assert main(["ingest", str(src), "--to", str(ds), "--link", "pumps"]) == 0  # a510 is there already
    return ds


def duck(ds, query):
    from sniffer.dataset.layout import open_dataset
    from sniffer.dataset.query import connect

    con = connect(open_dataset(str(ds)))
    try:
        return con.execute(query).fetchall()
    finally:
        con.close()


def test_dask_on_a_local_cluster_counts_what_duckdb_counts(fleet):
    import dask.dataframe as dd
    from distributed import Client, LocalCluster

    want_frames = dict(duck(fleet, "SELECT link, count(*) FROM frames GROUP BY link"))
    want_errors = {(link, unit): n for link, unit, n in duck(
        fleet, "SELECT link, unit, count(*) FROM annotations WHERE severity = 'error' GROUP BY ALL")}
    want_points = duck(fleet, "SELECT count(*), sum(value) FROM points WHERE crc_ok")[0]
    want_dates = {d.isoformat() for (d,) in duck(fleet, "SELECT DISTINCT date FROM frames")}
    assert set(want_frames) == {"drives", "pumps"} and sum(want_errors.values()) > 0

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      host="127.0.0.1") as cluster, Client(cluster) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        frames = dd.read_parquet(str(fleet / "frames"))
        got_frames = frames.groupby("link", observed=True).size().compute()
        assert {str(k): int(v) for k, v in got_frames.items()} == want_frames
        ann = dd.read_parquet(str(fleet / "annotations"), columns=["unit", "severity", "link"])
        errs = ann[ann.severity == "error"]
        got_errors = errs.groupby(["link", "unit"], observed=True).size().compute()
        assert {(str(link), int(unit)): int(v) for (link, unit), v in got_errors.items()} == want_errors
        pts = dd.read_parquet(str(fleet / "points"), columns=["value", "crc_ok"])
        good = pts[pts.crc_ok]
        n, total = dd.compute(good.value.size, good.value.sum())
        assert int(n) == want_points[0] and float(total) == pytest.approx(want_points[1])
        assert {str(d) for d in frames.date.unique().compute()} == want_dates
        assert frames.time.dtype.kind == "M" and str(frames.t.dtype) == "float64"
    assert dt.date.fromisoformat(next(iter(want_dates)))  # the partition is a date
