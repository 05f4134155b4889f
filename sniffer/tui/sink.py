"""A pipeline sink that hands frames to the TUI without flooding its event loop.

The capture (or replay) runs on its own thread and calls `frame()` thousands
of times a second; the sink only appends to a list under a lock.  The App
polls on a timer (15 Hz), takes frames into its FrameStore with `drain_into`
for a time budget (INTAKE_BUDGET_S, so a key never waits behind thousands of
frames), takes more in between polls while frames wait, and redraws once per
poll whatever the frame rate.

A replay decodes faster than the UI can take frames in: when `max_backlog`
frames wait, the UI has started draining and the frames' capture time runs
ahead of the wall clock (a live line never does), `frame()` waits until the UI has drained half of them, so a
million-frame replay does not pile up a million Frame objects in the sink.  The backlog is kept small
(2,000 frames): every waiting frame is a handful of objects each full garbage collection walks (at 30,000,
each took 100-800 ms of the UI thread while a 200k-frame replay loaded).

The register watch needs nothing else: each frame carries what it wrote into
its unit's register shadow (`Frame.writes`), so the sink never looks at the
decoders' state.

The byte view gets the reads (sniffer.analysis.reads): the sink marks each Chunk with
the frames its bytes went to (a ReadMarker on the capture thread) and keeps
at most RING_READS of them for the UI to drain (`drain_reads`); a viewer
attached to a capture gets them marked already (`reads`).
"""

from __future__ import annotations

import threading
import time
from collections import deque

from sniffer.events import CaptureInfo, Chunk
from sniffer.frame import Frame
from sniffer.analysis.reads import RING_READS, Read, ReadMarker
from sniffer.sinks.base import Sink

MAX_BACKLOG = 2_000  # frames waiting for the UI before a replay waits
INTAKE_BUDGET_S = 0.004  # the poll's turn at taking frames in (it also draws)
# between polls, while frames wait (a replay loading): turns this long, each followed by this much of the event
# loop's own work.  Turns of 4 ms every 20 ms left the UI thread idle 80 % of a load (656 frames/s under load);
# a key now waits about one turn, well within 100 ms.
INTAKE_TURN_S = 0.015
INTAKE_GAP_S = 0.002
INTAKE_CHUNK = 32  # frames drain_into hands over first, before it knows what a frame costs


class TuiSink(Sink):
    def __init__(self, max_backlog: int = MAX_BACKLOG) -> None:
        self._lock = threading.Lock()
        self._room = threading.Condition(self._lock)
        self.max_backlog = max_backlog
        self._released = False  # the UI stopped draining: never wait again
        self._ui = False  # someone drains (a UI polls): only then may a replay wait
        self._t_first: tuple[int, float] | None = None  # (capture t_ns, wall time) of the first frame
        self._pending: list[Frame] = []
        self._frame_cost_s: float | None = None  # what handing one frame to the UI took (drain_into)
        self._marker = ReadMarker()  # capture thread
        self._reads: deque[Read] = deque(maxlen=RING_READS)  # marked, waiting for the UI (the oldest go first)
        self.info: CaptureInfo | None = None
        self.started = threading.Event()
        self.closed = threading.Event()
        self.bytes_in = 0
        self.frames_in = 0
        self.t_start = time.monotonic()
        self.capture_path: str | None = None  # the MCAP being written, for the status bar
        self.error: str | None = None
        # a viewer attached to a publishing capture (attach.py): frames it does not have
        self.earlier_frames = 0  # before the backlog it was sent (they are in the MCAP)
        self.skipped_frames = 0  # dropped while it fell behind

    # ---- Sink protocol (capture thread)
    def start(self, info: CaptureInfo) -> None:
        self.info = info
        self.t_start = time.monotonic()
        self.started.set()

    def raw(self, event) -> None:
        if type(event) is Chunk:
            self.bytes_in += len(event.data)  # single writer; readers tolerate a stale int
            reads = self._marker.chunk(event)
            if reads:
                self.reads(reads)

    def frame(self, frame: Frame) -> None:
        reads = self._marker.frame(frame.index, len(frame.raw), frame.link)
        if reads:
            self.reads(reads)
        with self._lock:
            self._pending.append(frame)
            self.frames_in += 1
            full = len(self._pending) >= self.max_backlog
        if self._t_first is None:
            self._t_first = (frame.t_ns, time.monotonic())
        if full:
            self._wait_for_room(frame.t_ns)

    def _wait_for_room(self, t_ns: int) -> None:
        """A source faster than real time (a replay) waits for the UI; a live line never does, nor a
        sink nobody has drained yet (a pipeline collecting frames for later)."""
        t0, w0 = self._t_first
        if not self._ui or (t_ns - t0) / 1e9 < 2 * (time.monotonic() - w0) + 1:
            return
        with self._room:
            self._room.wait_for(lambda: len(self._pending) < self.max_backlog // 2 or self._released)

    def release(self) -> None:
        """The UI stops draining (it quits): never make the capture wait again."""
        with self._room:
            self._released = True
            self._room.notify_all()

    def frames(self, frames) -> None:
        """Bulk variant (benchmarks, tests, a viewer attached to a capture: frames decoded elsewhere)."""
        frames = list(frames)
        with self._lock:
            self._pending.extend(frames)
            self.frames_in += len(frames)

    def reads(self, reads) -> None:
        """Reads marked with their frames (the marker here, or a capture publishing them)."""
        with self._lock:
            self._reads.extend(reads)

    def close(self) -> None:
        reads = self._marker.flush()
        if reads:
            self.reads(reads)
        self.closed.set()

    # ---- UI thread
    def drain(self, limit: int | None = None) -> list[Frame]:
        """Take the frames that arrived since the last call (at most `limit`)."""
        with self._lock:
            if limit is None or len(self._pending) <= limit:
                out, self._pending = self._pending, []
            else:
                out = self._pending[:limit]
                del self._pending[:limit]  # in place: a memmove, not a copy of what stays
            self._ui = True
            self._room.notify_all()
        return out

    def drain_into(self, add, *, limit: int | None = None, budget_s: float | None = None,
                   clock=time.perf_counter) -> int:
        """Hand the waiting frames to `add` (a list at a time, in arrival order) until none wait, `limit`
        were handed, or `budget_s` has passed; returns how many were handed.

        Without a budget it is `add(drain(limit))`.  With one, the lists are sized to the time left at the
        cost a frame took so far (the first list: the last call's cost, else INTAKE_CHUNK frames), and the
        clock is read between them: the UI thread gives its event loop back after about `budget_s` however
        many frames wait or however slow a frame is (at least one frame goes each call)."""
        if budget_s is None:
            batch = self.drain(limit)
            if batch:
                add(batch)
            return len(batch)
        t0 = clock()
        done = 0
        cost = self._frame_cost_s
        size = max(1, int(budget_s / cost)) if cost else INTAKE_CHUNK
        while limit is None or done < limit:
            batch = self.drain(size if limit is None else min(size, limit - done))
            if not batch:
                break
            add(batch)
            done += len(batch)
            spent = clock() - t0
            cost = self._frame_cost_s = spent / done
            left = budget_s - spent
            if left <= 0:
                break
            size = max(1, int(left / cost)) if cost > 0 else INTAKE_CHUNK
        return done
    def drain_reads(self) -> list[Read]:
        """Take the reads marked since the last call."""
        with self._lock:
            out = list(self._reads)
            self._reads.clear()
        return out

    @property
    def backlog(self) -> int:
        return len(self._pending)
