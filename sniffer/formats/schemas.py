"""Every Arrow schema the sniffer writes, in one place: the Parquet export's two tables (the CSV export's
columns, written without Arrow) and the fleet dataset's three (sniffer.dataset), with the dataset's schema version.

The export's columns and their types are rows.py's (FRAMES, POINTS, ANNOTATIONS), made Arrow types here.
The dataset's tables are stable: a column is only ever added at the end (and SCHEMA_VERSION
raised), never renamed, retyped or dropped, so files written by an older sniffer read beside
newer ones (DuckDB's `union_by_name`, Dask's schema merge).  `link` and `date` are not in a
dataset file: they are its hive partition folders (`link=drives/date=2026-11-25/`).
"""

from __future__ import annotations

from sniffer.formats.rows import ANNOTATIONS, FRAMES, POINTS

SCHEMA_VERSION = 1  # the dataset's tables (dataset.json and every file's metadata say which)
PARTITIONS = ("link", "date")  # the dataset's hive partitions, in folder order
DATASET_TABLES = ("frames", "points", "annotations")
# added to each dataset table after its rows' columns: wall-clock time (null when the capture does not
# know it) and the capture segment the row came from (its file name in the dataset, sniffer.dataset)
DATASET_EXTRA = ("time", "capture")


def _schema(columns):
    """An Arrow schema of rows.py's (name, type) columns."""
    import pyarrow as pa

    types = {"int": pa.int64(), "float": pa.float64(), "str": pa.string(), "bool": pa.bool_()}
    return pa.schema([(name, types[kind]) for name, kind in columns])


def export_schemas():
    """The export's frames and points tables (plain types: int64, float64, bool, string); `link` last
    (null for one line): in the dataset it is the partition folder instead (`dataset_bases`)."""
    return _schema(FRAMES), _schema(POINTS)


def annotation_schema():
    """One row per annotation (rows.annotation_rows): the frame it is on and what it says."""
    return _schema(ANNOTATIONS)


def dataset_bases() -> tuple:
    """The rows' schemas of the dataset's three tables: the export's frames and points and the annotations,
    without the partition columns (a row's link is its folder; a partition column comes last in a row)."""
    import pyarrow as pa

    out = []
    for schema in (*export_schemas(), annotation_schema()):
        kept = [f for f in schema if f.name not in PARTITIONS]
        assert schema.names[: len(kept)] == [f.name for f in kept], "a partition column must come last"
        out.append(pa.schema(kept))
    return tuple(out)


def dataset_schemas() -> dict:
    """The dataset's tables: name -> schema (the rows' columns, then `time` and `capture`)."""
    import pyarrow as pa

    extra = [pa.field("time", pa.timestamp("ns", tz="UTC")), pa.field("capture", pa.string())]
    return {name: pa.schema(list(base) + extra) for name, base in zip(DATASET_TABLES, dataset_bases())}


def described(schema) -> list[list[str]]:
    """[[column, type], ...]: a schema as dataset.json lists it."""
    return [[f.name, str(f.type)] for f in schema]
