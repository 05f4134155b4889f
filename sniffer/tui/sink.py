"""A pipeline sink that hands frames to the TUI without flooding its event loop.

The capture (or replay) runs on its own thread and calls `frame()` thousands
of times a second; the sink only appends to a list under a lock.  The App
polls `drain()` on a timer (10-20 Hz) and adds the batch to its FrameStore,
so the UI thread does one redraw per tick whatever the frame rate.
"""

from __future__ import annotations

import threading
import time

from ..events import CaptureInfo, Chunk
from ..frame import Frame


class TuiSink:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: list[Frame] = []
        self.info: CaptureInfo | None = None
        self.started = threading.Event()
        self.closed = threading.Event()
        self.bytes_in = 0
        self.frames_in = 0
        self.t_start = time.monotonic()
        self.capture_path: str | None = None  # the MCAP being written, for the status bar
        self.error: str | None = None

    # ---- Sink protocol (capture thread)
    def start(self, info: CaptureInfo) -> None:
        self.info = info
        self.t_start = time.monotonic()
        self.started.set()

    def raw(self, event) -> None:
        if type(event) is Chunk:
            self.bytes_in += len(event.data)  # single writer; readers tolerate a stale int

    def frame(self, frame: Frame) -> None:
        with self._lock:
            self._pending.append(frame)
        self.frames_in += 1

    def frames(self, frames) -> None:
        """Bulk variant (benchmarks, replays that batch)."""
        frames = list(frames)
        with self._lock:
            self._pending.extend(frames)
        self.frames_in += len(frames)

    def close(self) -> None:
        self.closed.set()

    # ---- UI thread
    def drain(self, limit: int | None = None) -> list[Frame]:
        """Take the frames that arrived since the last call (at most `limit`)."""
        with self._lock:
            if limit is None or len(self._pending) <= limit:
                out, self._pending = self._pending, []
            else:
                out, self._pending = self._pending[:limit], self._pending[limit:]
        return out

    @property
    def backlog(self) -> int:
        return len(self._pending)
