"""A rich progress bar for long replays/exports (stderr): events, events/s, ETA.

The total is known for an MCAP closed cleanly (its summary counts the /raw
events); for other sources the bar shows a count, the rate and the elapsed
time, without ETA.  Ctrl-C is not caught here: the export's `finally`
closes the bar and the output file.
"""

from __future__ import annotations

import os
import sys


def estimate_events(path) -> int | None:
    """Number of source events, when the file says it cheaply (MCAP summary); else None."""
    try:
        from mcap.reader import make_reader

        from .mcap_format import RAW_TOPIC
        from .sources import mcapsrc

        if not mcapsrc.sniff(path):
            return None
        with open(path, "rb") as fh:
            summary = make_reader(fh).get_summary()
        if summary is None or summary.statistics is None:
            return None
        counts = summary.statistics.channel_message_counts
        return sum(counts.get(cid, 0) for cid, ch in summary.channels.items() if ch.topic == RAW_TOPIC) or None
    except Exception:  # noqa: BLE001 - an estimate only: a damaged file still replays, without ETA
        return None


class ReplayProgress:
    def __init__(self, capture, every: int = 500, events=None) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn,
        )

        self.every = every
        self._n = 0
        self.total = estimate_events(capture)
        if self.total is None and events is not None:
            import operator

            # sources that read their file up front (CSV) know how many events they hold
            self.total = operator.length_hint(events, 0) or None
        self._progress = Progress(
            SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
            TextColumn("{task.completed} events"), TextColumn("{task.fields[frames]}"),
            TextColumn("{task.fields[rate]}"),
            TimeElapsedColumn(), TimeRemainingColumn(),
            console=Console(file=sys.stderr), transient=True,
        )
        self._task = self._progress.add_task(os.path.basename(os.fspath(capture)), total=self.total,
                                             rate="", frames="")
        self._progress.start()
        import time

        self._clock = time.monotonic
        self._t0 = self._clock()
        self.frames = None  # a callable giving frames decoded so far, if the caller has one

    def update(self, i: int, ev) -> None:
        self._n = i + 1
        if self._n % self.every == 0:
            fields = {}
            if self.frames is not None:
                n = self.frames()
                dt = max(1e-9, self._clock() - self._t0)
                fields = {"frames": f"{n:,} frames", "rate": f"{n / dt:,.0f} frames/s"}
            else:
                speed = self._progress.tasks[0].speed
                fields = {"rate": f"{speed:,.0f} events/s" if speed else ""}
            self._progress.update(self._task, completed=self._n, **fields)

    def close(self) -> None:
        self._progress.update(self._task, completed=self._n)
        self._progress.stop()
