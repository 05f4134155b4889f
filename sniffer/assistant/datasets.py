"""SQL over a fleet dataset for an assistant: read-only (`sniffer query --read-only`: the views only, no file
opened, written or attached by SQL, no extension), at most a number of rows, stopped after a time limit."""

from __future__ import annotations

import threading

from sniffer.assistant.bounds import ANSWER_BYTES, fit, scrub

MAX_ROWS = 1_000
MAX_SECONDS = 30.0


def query(folder: str, sql: str, max_rows: int = 100, seconds: float = 10.0) -> dict:
    """{columns, rows, truncated}: the first `max_rows` rows of `sql` on the dataset's views; ValueError (one
    line) for SQL DuckDB refuses, or a query still running after `seconds`."""
    import duckdb

    from sniffer.dataset.layout import open_dataset
    from sniffer.dataset.query import VIEWS, connect

    con = connect(open_dataset(folder), read_only=True)
    stopped = threading.Event()

    def stop():
        stopped.set()
        con.interrupt()

    timer = threading.Timer(seconds, stop)
    timer.start()
    try:
        cursor = con.execute(sql)
        if cursor is None or cursor.description is None:
            raise ValueError(f"no query in it (the views: {', '.join(VIEWS)})")
        columns = [c[0] for c in cursor.description]
        rows = cursor.fetchmany(max_rows + 1)
    except duckdb.Error as e:
        if stopped.is_set():
            raise ValueError(f"the query ran over {seconds:g} s and was stopped") from None
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ValueError(first) from None
    finally:
        timer.cancel()
        con.close()
    more = len(rows) > max_rows
    data = [scrub(list(r)) for r in rows[:max_rows]]
    kept, cut = fit(data, ANSWER_BYTES - 1_000)
    return {"dataset": folder, "columns": scrub(columns), "rows": kept, "truncated": more or cut}
