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


def cmd_query(spec: CaptureSpec, args) -> int:
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
