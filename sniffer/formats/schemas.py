"""Every Arrow schema the sniffer writes, in one place: the CSV/Parquet export's two tables and the
fleet dataset's three (sniffer.dataset), with the dataset's schema version.

The export's columns are rows.py's (FRAME_COLUMNS, POINT_COLUMNS), typed here field by field.
The dataset's tables are stable: a column is only ever added at the end (and SCHEMA_VERSION
raised), never renamed, retyped or dropped, so files written by an older sniffer read beside
newer ones (DuckDB's `union_by_name`, Dask's schema merge).  `link` and `date` are not in a
dataset file: they are its hive partition folders (`link=drives/date=2026-11-25/`).
"""

from __future__ import annotations

from sniffer.formats.rows import ANNOTATION_COLUMNS, FRAME_COLUMNS, POINT_COLUMNS

SCHEMA_VERSION = 1  # the dataset's tables (dataset.json and every file's metadata say which)
PARTITIONS = ("link", "date")  # the dataset's hive partitions, in folder order
DATASET_TABLES = ("frames", "points", "annotations")
# added to each dataset table after its rows' columns: wall-clock time (null when the capture does not
# know it) and the capture segment the row came from (its file name in the dataset, sniffer.dataset)
DATASET_EXTRA = ("time", "capture")


def _types():
    import pyarrow as pa

    return pa.int64(), pa.float64(), pa.string(), pa.bool_()


def export_schemas():
    """The export's frames and points tables (plain types: int64, float64, bool, string); `link` last
    (null for one line): in the dataset it is the partition folder instead (`dataset_bases`)."""
    import pyarrow as pa

    i, f, s, b = _types()
    frames = pa.schema([
        ("index", i), ("t", f), ("t_end", f), ("t_wall_ns", i), ("protocol", s), ("role", s), ("unit", i),
        ("function", i), ("crc_ok", b), ("exception_code", i), ("model", s), ("pair", i), ("latency_ms", f),
        ("n_points", i), ("annotations", s), ("summary", s), ("raw", s), ("channel", s), ("time_source", s),
        ("noise_reason", s), ("link", s),
    ])
    points = pa.schema([
        ("frame", i), ("t", f), ("unit", i), ("function", i), ("role", s), ("crc_ok", b), ("model", s),
        ("address", i), ("name", s), ("id", s), ("raw", i), ("value", f), ("value_text", s), ("eng_unit", s),
        ("link", s),
    ])
    assert frames.names == list(FRAME_COLUMNS) and points.names == list(POINT_COLUMNS)
    return frames, points


def annotation_schema():
    """One row per annotation (rows.annotation_rows): the frame it is on and what it says."""
    import pyarrow as pa

    i, f, s, b = _types()
    schema = pa.schema([
        ("frame", i), ("t", f), ("unit", i), ("function", i), ("role", s), ("crc_ok", b), ("model", s),
        ("code", s), ("severity", s), ("detail", s), ("span_start", i), ("span_end", i),
    ])
    assert schema.names == list(ANNOTATION_COLUMNS)
    return schema


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
