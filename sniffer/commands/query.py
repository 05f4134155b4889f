"""`sniffer query DIR "SQL"` / `--preset NAME`: SQL over a fleet dataset with DuckDB (sniffer.dataset.query).

The result goes to stdout as a table, CSV or JSON.  A missing dataset or SQL that DuckDB
refuses is one line on stderr and exit code 2; a query stopped with Ctrl-C, 130.  The SQL runs with
the user's rights; `--read-only` takes them away (no file opened or written by SQL, nothing
installed: sniffer.dataset.query) for SQL that comes from elsewhere.
"""

from __future__ import annotations

import sys

from sniffer import need
from sniffer.dataset.layout import open_dataset
from sniffer.dataset.query import PRESETS, VIEWS, connect, write
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK, UsageError
from sniffer.commands.flags import command_parser, number


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "query", help="SQL over a fleet dataset with DuckDB: views frames, points, annotations, "
                                  "captures (docs/fleet.md)",
        description=f"""\
            SQL over a fleet dataset (`sniffer export ... --to dataset DIR`, `sniffer ingest`) with DuckDB, or
            a named query (--preset).  Views: {', '.join(VIEWS)}.""",
        examples=["sniffer query /srv/fleet --preset units",
                  "sniffer query /srv/fleet \"SELECT link, count(*) FROM frames GROUP BY link\"",
                  "sniffer query /srv/fleet --preset faults --format csv > faults.csv"])
    p.add_argument("dataset", metavar="DIR", help="the dataset folder")
    p.add_argument("sql", nargs="?", help="a query, e.g. \"SELECT link, count(*) FROM frames GROUP BY link\"")
    p.add_argument("--preset", choices=sorted(PRESETS), help="a named query instead: " + "; ".join(
        f"{name}: {p.about}" for name, p in sorted(PRESETS.items())))
    p.add_argument("--format", choices=["table", "csv", "json"], default="table",
                   help="output: an aligned table, CSV, or JSON (an array of objects)")
    p.add_argument("--max-rows", type=number(int, "--max-rows", 1, 10**9), default=100,
                   help="rows a table shows (csv and json give every row)")
    p.add_argument("--show-sql", action="store_true", help="print the preset's SQL instead of running it")
    p.add_argument("--read-only", action="store_true",
                   help="for SQL from elsewhere (a dashboard, a script): the SQL may read the dataset's views "
                        "only, never open, write or attach a file, nor install an extension (without it, "
                        "DuckDB runs with your rights)")


def run(spec: CaptureSpec, args) -> int:
    if (args.sql is None) == (args.preset is None):
        raise UsageError("query needs SQL or --preset NAME (one of them): "
                         f"sniffer query DIR \"SELECT ... FROM frames\" (views: {', '.join(VIEWS)}), "
                         f"or --preset {'|'.join(sorted(PRESETS))}")
    sql = PRESETS[args.preset].sql if args.preset else args.sql
    if args.show_sql:
        print(sql)
        return EXIT_OK
    need("fleet", "sniffer query")
    ds = open_dataset(args.dataset)
    import duckdb

    con = None
    try:
        con = connect(ds, read_only=args.read_only)
        cursor = con.execute(sql)
        if cursor is None:  # DuckDB found no statement: only blanks, comments, semicolons
            raise UsageError("query: no SQL statement in it (only blanks or comments): "
                             f"sniffer query DIR \"SELECT ... FROM frames\" (views: {', '.join(VIEWS)})")
        write(cursor, args.format, sys.stdout, max_rows=args.max_rows)
    except duckdb.Error as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise UsageError(f"query: {first}") from None
    finally:
        if con is not None:
            con.close()
    return EXIT_OK
