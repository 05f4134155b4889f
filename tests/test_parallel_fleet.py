"""A fleet's captures into a dataset by worker processes (--jobs) and on a Dask cluster (--dask): the dataset one
process makes (sniffer.parallel.fleet): the same Parquet files, the same manifest entries (but when they were
taken in), the same lines; a file identical to one taken in earlier in the same run is skipped, a damaged one
is not taken in, as in one process."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from sniffer.cli import main

CAPTURES = Path(__file__).resolve().parent.parent / "captures" / "sim"


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Two cabinets' folders: four captures, one of them twice, one cut short (not whole: not taken in)."""
    root = tmp_path_factory.mktemp("fleet")
    for cab, names in (("cab1", ("errors", "tds-v8")), ("cab2", ("a510", "spl-ascii"))):
        (root / cab).mkdir()
        for name in names:
            shutil.copy(CAPTURES / f"{name}.mcap", root / cab / f"{name}.mcap")
    shutil.copy(CAPTURES / "errors.mcap", root / "cab2" / "again.mcap")
    data = (CAPTURES / "pd-series.mcap").read_bytes()
    (root / "cab2" / "killed.mcap").write_bytes(data[: len(data) // 2])
    return root


def _dataset(root) -> dict:
    """Every file of a dataset: its bytes' hash (a manifest entry: its JSON but for when it was taken in)."""
    out = {}
    for here, _dirs, names in os.walk(root):
        for n in names:
            p = os.path.join(here, n)
            rel = os.path.relpath(p, root)
            data = open(p, "rb").read()
            if rel.startswith("_manifest"):
                entry = json.loads(data)
                assert entry.pop("ingested_at")
                out[rel] = entry
            else:
                out[rel] = hashlib.sha256(data).hexdigest()
    return out


def _ingest(capfd, fleet, ds, *flags) -> tuple[int, str]:
    capfd.readouterr()
    rc = main(["ingest", str(fleet), "--to", str(ds), *flags])
    return rc, capfd.readouterr().err.replace(str(ds), "DS")


@pytest.fixture(scope="module")
def one(tmp_path_factory, fleet):
    ds = tmp_path_factory.mktemp("one") / "ds"
    rc = main(["ingest", str(fleet), "--to", str(ds), "--jobs", "1"])
    return rc, ds


def test_worker_processes_fill_the_dataset_one_process_fills(capfd, tmp_path, fleet, one):
    rc1, ds1 = one
    capfd.readouterr()
    rc1, err1 = _ingest(capfd, fleet, tmp_path / "again", "--jobs", "1")
    rc2, err2 = _ingest(capfd, fleet, tmp_path / "ds", "--jobs", "2")
    assert rc1 == rc2 == 2  # the killed capture is not taken in
    assert err1.replace(str(tmp_path / "again"), "DS") == err2.replace(str(tmp_path / "ds"), "DS")
    assert "again.mcap: already in the dataset as errors-" in err2
    assert _dataset(ds1) == _dataset(tmp_path / "ds")
    assert not os.path.exists(tmp_path / "ds" / "_staging")


def test_a_dask_cluster_fills_the_dataset_one_process_fills(capfd, tmp_path, fleet, one):
    pytest.importorskip("distributed", reason="dask[distributed] is in the test extra")
    from distributed import LocalCluster

    _rc, ds1 = one
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      host="127.0.0.1") as cluster:
        rc, err = _ingest(capfd, fleet, tmp_path / "ds", "--dask", cluster.scheduler_address)
    assert rc == 2, err
    assert _dataset(ds1) == _dataset(tmp_path / "ds")


def test_a_dask_address_nobody_listens_on_is_one_line(capfd, tmp_path, fleet):
    pytest.importorskip("distributed", reason="dask[distributed] is in the test extra")
    rc, err = _ingest(capfd, fleet, tmp_path / "ds", "--dask", "tcp://127.0.0.1:9")
    assert rc == 2
    assert err.count("\n") == 1 and "--dask tcp://127.0.0.1:9: cannot connect (Connection refused)" in err
