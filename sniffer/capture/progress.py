"""A progress bar for long replays and exports (stderr): frames, frames/s, ETA.

The bar advances by the bytes of the file read so far when the source can say
it (`FileSource.position()`), else by events against the count an MCAP's
summary gives, else it shows a count and the rate without ETA.  Ctrl-C is not
caught here: the session's end closes the bar's owner's files.
"""

from __future__ import annotations

import os
import sys
import time


def estimate_events(path) -> int | None:
    """Number of source events, when the file says it cheaply (MCAP summary); else None."""
    try:
        from mcap.reader import make_reader

        from sniffer.formats.mcap.format import RAW_TOPIC
        from sniffer.formats.mcap import reader as mcapsrc

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
    def __init__(self, capture, *, source=None, frames=None, every: int = 500) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn,
        )

        self.every = every
        self._n = 0
        self._source = source
        self._position = getattr(source, "position", None)
        self.frames = frames  # a callable giving frames decoded so far
        pos = self._position() if self._position else None
        self._by_bytes = pos is not None
        self.total = pos[1] if pos else estimate_events(capture)
        unit = "bytes" if self._by_bytes else "events"
        self._progress = Progress(
            SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
            TextColumn(f"{{task.completed}} {unit}"), TextColumn("{task.fields[frames]}"),
            TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn(),
            console=Console(file=sys.stderr), transient=True,
        )
        self._task = self._progress.add_task(os.path.basename(os.fspath(capture)), total=self.total,
                                             rate="", frames="")
        self._progress.start()
        self._t0 = time.monotonic()

    def update(self, _event=None) -> None:
        self._n += 1
        if self._n % self.every:
            return
        fields = {}
        if self.frames is not None:
            n = self.frames()
            dt = max(1e-9, time.monotonic() - self._t0)
            fields = {"frames": f"{n:,} frames", "rate": f"{n / dt:,.0f} frames/s"}
        done = self._n
        if self._by_bytes:
            pos = self._position()
            done = pos[0] if pos else done
        self._progress.update(self._task, completed=done, **fields)

    def close(self) -> None:
        if self._by_bytes and self.total:
            self._progress.update(self._task, completed=self.total)
        else:
            self._progress.update(self._task, completed=self._n)
        self._progress.stop()
