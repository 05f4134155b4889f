"""SQL over a dataset with DuckDB (embedded): views, the named queries, and their output.

    con = connect(open_dataset("fleet"))          # views frames, points, annotations, captures
    write(con.execute(PRESETS["faults"].sql), "table", sys.stdout)

The views read every file of a table under the hive partitions (`link` VARCHAR, `date` DATE,
given, not guessed: a link named `7` stays text), by column name (`union_by_name`: files of
an older schema version read beside newer ones).  A table no capture has rows for yet is an
empty view with its columns, so every query runs on a new dataset.

DuckDB runs with the user's rights: SQL may read any file, write one (`COPY ... TO`), attach a
database or install an extension from the network.  `read_only=True` (query --read-only, for SQL
that comes from elsewhere) reads the tables through pyarrow datasets handed to DuckDB, then turns
DuckDB's external access off and locks its configuration: no file is opened by SQL, the dataset's
included (nothing can be written into it), and no extension is installed or loaded; it has no temporary
folder either (DuckDB's default, `./.tmp` of the current folder, stays open to SQL with external access off).
"""

from __future__ import annotations

import csv
import datetime as dt
import decimal
import glob
import json
import math
import os
from dataclasses import dataclass

from decoders.registry import code_book
from sniffer import codes as C
from sniffer.formats.schemas import DATASET_TABLES, PARTITIONS, dataset_schemas
from sniffer.analysis.unitfigures import QUANTILES
from sniffer.dataset.layout import Dataset


@dataclass(frozen=True)
class Preset:
    about: str
    sql: str


def _literal(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _codes(*categories: str) -> str:
    """The codes of `categories` (sniffer.codes: each code declares its own) as an SQL list."""
    return "(" + ", ".join(_literal(c) for c in sorted(code_book().in_category(*categories))) + ")"


# what a frame's annotations make it, one row a frame (the categories sniffer.analysis.unitfigures counts)
_FRAME_CATEGORIES = f"""SELECT capture, frame,
         bool_or(code IN {_codes(C.TIMEOUT_CAT)}) AS timeout, bool_or(code IN {_codes(C.END_OF_CAPTURE_CAT)}) AS at_end,
         bool_or(code IN {_codes(C.LATE_CAT)}) AS late, bool_or(code IN {_codes(C.RETRY_CAT)}) AS retry,
         bool_or(code IN {_codes(C.EXCEPTION_CAT)}) AS exception, bool_or(code IN {_codes(C.FAULT_CAT)}) AS fault,
         bool_or(code IN {_codes(C.ALARM_CAT)}) AS alarm
  FROM annotations GROUP BY capture, frame"""
_QUANTILES = ",\n       ".join(f"quantile_disc(latency_ms, {q}) FILTER (WHERE paired) AS {name}"
                               for name, q in QUANTILES)

# analysis/unitfigures.py's UnitFigures, figure by figure (its docstring defines each; docs/figures.md too);
# an aggregate leaves out NULL: a latency counts where the response is paired and has one
UNITS_SQL = f"""WITH a AS (
  {_FRAME_CATEGORIES}
), u AS (
  SELECT f.link, f.unit, f.role, f.crc_ok, f.latency_ms, f.role = 'response' AND f.pair IS NOT NULL AS paired,
         a.timeout, a.at_end, a.late, a.retry, a.exception, a.fault, a.alarm
  FROM frames f LEFT JOIN a ON a.capture = f.capture AND a.frame = f.index
  WHERE f.unit IS NOT NULL AND f.protocol <> 'noise'
)
SELECT link, unit, count(*) FILTER (WHERE crc_ok) = 0 AS ghost,
       count(*) FILTER (WHERE role = 'request') AS requests,
       count(*) FILTER (WHERE role = 'response') AS responses,
       count(*) FILTER (WHERE NOT crc_ok) AS crc_errors,
       count(*) FILTER (WHERE role = 'response' AND exception) AS exceptions,
       count(*) FILTER (WHERE role = 'request' AND timeout) AS timeouts,
       count(*) FILTER (WHERE role = 'request' AND retry) AS retries,
       count(*) FILTER (WHERE fault) AS faults,
       count(*) FILTER (WHERE alarm) AS alarms,
       count(*) FILTER (WHERE role = 'response' AND late) AS late,
       count(*) FILTER (WHERE role = 'request' AND at_end) AS unanswered_at_end,
       count(*) FILTER (WHERE paired AND latency_ms IS NULL) AS unmeasured,
       count(latency_ms) FILTER (WHERE paired) AS lat_n,
       min(latency_ms) FILTER (WHERE paired) AS lat_min,
       {_QUANTILES},
       max(latency_ms) FILTER (WHERE paired) AS lat_max
FROM u
GROUP BY link, unit
ORDER BY link, unit"""

PRESETS = {
    "units": Preset(
        "every unit's figures, as the TUI, the report, status, diff and MQTT count them: requests, responses, "
        "CRC errors, exceptions, timeouts, retries, faults, alarms, late, unanswered at the end, latency "
        "(ms; quantiles by the nearest rank)", UNITS_SQL),
    "faults": Preset(
        "problems by link, unit and code: CRC errors, exceptions, timeouts, drive faults and alarms, "
        "how often, first and last seen",
        f"""SELECT link, unit, code, severity, count(*) AS n, min(time) AS first, max(time) AS last,
       count(DISTINCT capture) AS captures, any_value(detail) AS example
FROM annotations
WHERE severity = 'error'
   OR code IN {_codes(C.EXCEPTION_CAT, C.FAULT_CAT, C.ALARM_CAT, C.TIMEOUT_CAT, C.GAP_CAT)}
GROUP BY link, unit, code, severity
ORDER BY n DESC, link, unit, code"""),
    "latency": Preset(
        "response latency per link and unit: responses with a latency, median, p95, p99 and max (ms; quantiles "
        "by the nearest rank, as every view has them)",
        """SELECT link, unit, count(*) AS measured,
       quantile_disc(latency_ms, 0.5) AS median_ms, quantile_disc(latency_ms, 0.95) AS p95_ms,
       quantile_disc(latency_ms, 0.99) AS p99_ms, max(latency_ms) AS max_ms
FROM frames
WHERE unit IS NOT NULL AND protocol <> 'noise' AND role = 'response' AND pair IS NOT NULL AND latency_ms IS NOT NULL
GROUP BY link, unit
ORDER BY link, unit"""),
    "writes": Preset(
        "every write request (function 5, 6, 15, 16, 22, 23) with its outcome: confirmed, exception, "
        "bad CRC, no response, broadcast",
        """SELECT q.link, q.time, q.capture, q.index AS frame, q.unit, q.function, q.summary AS write,
       CASE WHEN q.unit = 0 THEN 'broadcast'
            WHEN NOT q.crc_ok THEN 'request CRC bad'
            WHEN r.index IS NULL THEN 'no response'
            WHEN r.exception_code IS NOT NULL THEN 'exception ' || r.exception_code
            WHEN NOT r.crc_ok THEN 'response CRC bad'
            ELSE 'confirmed' END AS outcome,
       r.latency_ms
FROM frames q
LEFT JOIN frames r ON r.capture = q.capture AND r.index = q.pair AND r.role = 'response'
WHERE q.role = 'request' AND q.function IN (5, 6, 15, 16, 22, 23)
ORDER BY q.time, q.capture, q.index"""),
}


def _partitioned(schema):
    import pyarrow as pa

    return schema.append(pa.field(PARTITIONS[0], pa.string())).append(pa.field(PARTITIONS[1], pa.date32()))


def _captures(ds: Dataset):
    """The manifest as a table (entries that cannot be read are left out, as when ingesting)."""
    import pyarrow as pa

    i, s = pa.int64(), pa.string()
    schema = pa.schema([("capture", s), ("source", s), ("size", i), ("sha256", s), ("frames", i), ("points", i),
                        ("annotations", i), ("links", pa.list_(s)), ("partitions", pa.list_(s)), ("settings", s),
                        ("first", pa.timestamp("ns", tz="UTC")), ("last", pa.timestamp("ns", tz="UTC")),
                        ("ingested_at", s), ("sniffer_version", s)])
    rows = []
    for e in ds.manifest():
        row = {name: e.get(name) for name in schema.names}
        row["first"], row["last"] = e.get("first_ns"), e.get("last_ns")
        rows.append(row)
    try:
        return pa.Table.from_pylist(rows, schema=schema)
    except (pa.ArrowInvalid, pa.ArrowTypeError, TypeError, ValueError, OverflowError):  # edited by hand: those that fit
        return pa.Table.from_pylist([r for r in rows if _fits(r, schema)], schema=schema)


def _fits(row: dict, schema) -> bool:
    import pyarrow as pa

    try:
        pa.Table.from_pylist([row], schema=schema)
    except (pa.ArrowInvalid, pa.ArrowTypeError, TypeError, ValueError, OverflowError):
        return False
    return True


def _arrow_table(ds: Dataset, name: str, schema, files: list[str]):
    """The table's files as a pyarrow dataset (the partitions from the folders, older files' missing
    columns as nulls): what DuckDB scans with external access off."""
    import pyarrow as pa
    import pyarrow.dataset as pads

    hive = pads.partitioning(pa.schema([pa.field(PARTITIONS[0], pa.string()), pa.field(PARTITIONS[1], pa.date32())]),
                             flavor="hive")
    return pads.dataset(files, schema=_partitioned(schema), format="parquet", partitioning=hive,
                        partition_base_dir=os.path.join(ds.root, name))


def connect(ds: Dataset, *, threads: int | None = None, read_only: bool = False):
    """An in-memory DuckDB connection with the dataset's views (frames, points, annotations, captures);
    `read_only`: SQL can open no file and install nothing (see the module doc)."""
    import duckdb

    con = duckdb.connect(config={"threads": threads} if threads else {})
    hive_types = "{" + ", ".join(f"{_literal(p)}: {_literal(t)}" for p, t in zip(PARTITIONS, ("VARCHAR", "DATE"))) + "}"
    for name, schema in dataset_schemas().items():
        pattern = os.path.join(glob.escape(ds.root), name, f"{PARTITIONS[0]}=*", f"{PARTITIONS[1]}=*", "*.parquet")
        files = sorted(glob.glob(pattern)) if read_only else None
        if not files and (read_only or next(glob.iglob(pattern), None) is None):
            con.register(f"_{name}_empty", _partitioned(schema).empty_table())
            con.execute(f"CREATE VIEW {name} AS SELECT * FROM _{name}_empty")
            continue
        if read_only:
            con.register(f"_{name}_files", _arrow_table(ds, name, schema, files))
            con.execute(f"CREATE VIEW {name} AS SELECT * FROM _{name}_files")
            continue
        con.execute(f"CREATE VIEW {name} AS SELECT * FROM read_parquet({_literal(pattern)}, hive_partitioning = true, "
                    f"hive_types = {hive_types}, union_by_name = true)")
    con.register("_captures", _captures(ds))
    con.execute("CREATE VIEW captures AS SELECT * FROM _captures")
    if read_only:
        # temp_directory: DuckDB spills to ./.tmp of the current folder by default, and external access off still
        # allows its temp directory: SQL could read and write files there.  None: a query too big for memory fails.
        for setting in ("SET temp_directory = ''", "SET enable_external_access = false",
                        "SET autoinstall_known_extensions = false",
                        "SET autoload_known_extensions = false",
                        "SET python_enable_replacements = false",  # no Python variable is a table either
                        "SET lock_configuration = true"):
            con.execute(setting)
    return con


VIEWS = (*DATASET_TABLES, "captures")
FETCH = 2_048


def _text(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (dt.datetime, dt.date, dt.time)):
        return v.isoformat()
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_text(x) for x in v) + "]"
    return str(v)


CELL = 60  # characters of a table cell (csv and json keep everything)


def _cell(v) -> str:
    text = "NULL" if v is None else _text(v)
    return text if len(text) <= CELL else text[:CELL - 1] + "…"


def _json_default(v):
    if isinstance(v, decimal.Decimal):
        return float(v)
    if isinstance(v, (dt.date, dt.time)):
        return v.isoformat()
    if isinstance(v, (dt.timedelta, bytes, bytearray, memoryview)):
        return str(v) if isinstance(v, dt.timedelta) else bytes(v).hex()
    return str(v)


def _finite(v):
    """A value for the standard json module as orjson writes it: NaN and infinities are null."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {str(k): _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    return v


def write(cursor, fmt: str, out, *, max_rows: int = 100) -> int:
    """The result as `table` (aligned text, the first `max_rows` rows), `csv` or `json` (an array of
    objects), fetched and written a block at a time; returns the number of rows written."""
    names = [d[0] for d in cursor.description or ()]
    if fmt == "csv":
        w = csv.writer(out, lineterminator="\n")
        w.writerow(names)
        n = 0
        while rows := cursor.fetchmany(FETCH):
            w.writerows([[_text(v) for v in r] for r in rows])
            n += len(rows)
        return n
    if fmt == "json":
        import orjson

        n = 0
        out.write("[")
        while rows := cursor.fetchmany(FETCH):
            for r in rows:
                out.write(",\n" if n else "\n")
                row = dict(zip(names, r))
                try:
                    text = orjson.dumps(row, default=_json_default, option=orjson.OPT_NON_STR_KEYS).decode()
                except orjson.JSONEncodeError:  # what orjson refuses: an integer past 64 bits, a time with a zone
                    text = json.dumps(_finite(row), default=_json_default, allow_nan=False)
                out.write(text)
                n += 1
        out.write("\n]\n" if n else "]\n")
        return n
    rows = cursor.fetchmany(max_rows + 1)
    more = len(rows) > max_rows
    rows = rows[:max_rows]
    cells = [[_cell(v) for v in r] for r in rows]
    numeric = [all(isinstance(r[i], (int, float, decimal.Decimal)) and not isinstance(r[i], bool)
                   for r in rows if r[i] is not None) for i in range(len(names))]
    widths = [max([len(nm)] + [len(c[i]) for c in cells]) for i, nm in enumerate(names)]
    lines = ["  ".join(nm.rjust(w) if num else nm.ljust(w) for nm, w, num in zip(names, widths, numeric)).rstrip(),
             "  ".join("-" * w for w in widths)]
    for c in cells:
        lines.append("  ".join(v.rjust(w) if num else v.ljust(w) for v, w, num in zip(c, widths, numeric)).rstrip())
    out.write("\n".join(lines) + "\n")
    if more:
        out.write(f"(the first {max_rows} rows; more not shown: --max-rows N, or --format csv / json for all)\n")
    else:
        out.write(f"({len(rows)} row{'s' if len(rows) != 1 else ''})\n")
    return len(rows)
