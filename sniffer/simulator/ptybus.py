"""A pseudo-terminal that plays simulated traffic to a live sniffer.

The sniffer opens `PtyBus.port` like a real adapter and cannot tell the
difference except for timing, which a pty does not keep per byte: each
frame goes out in one write at its due time, so the reads the sniffer sees
look like an adapter's (per read, host-timed).

The pty is the only honest way to test the live path without hardware: the
real open/read/termios code runs against a real tty.  It also catches a
sniffer that is not passive, because anything it writes comes out of the
master side, which we drain and count.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import time
import tty
from collections.abc import Iterable
from dataclasses import dataclass

from sniffer.simulator.wire import WireFrame

_POLL_S = 0.02  # how often a waiting play() looks at stop_event and drains


@dataclass(frozen=True, slots=True)
class PlayStats:
    frames: int
    bytes: int
    stopped: bool  # stop_event ended the play early


class PtyBus:
    def __init__(self) -> None:
        self.master_fd, self.slave_fd = os.openpty()
        # Raw mode on the slave's termios (shared by both ends): no echo, no
        # CR/LF translation, no line editing, so every byte arrives as sent.
        # Holding our own slave fd keeps the pty alive while the sniffer
        # closes and reopens the port, and keeps the settings in place.
        tty.setraw(self.slave_fd, termios.TCSANOW)
        os.set_blocking(self.master_fd, False)
        self.port = os.ttyname(self.slave_fd)
        self.bytes_received_from_sniffer = 0
        self.received = bytearray()  # what came back; should stay empty for a passive sniffer
        self._lock = threading.Lock()
        self._closed = False

    def __enter__(self) -> "PtyBus":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def drain(self) -> int:
        """Read whatever the slave side wrote; returns the bytes read now."""
        n = 0
        with self._lock:
            if self._closed:
                return 0
            while True:
                try:
                    data = os.read(self.master_fd, 4096)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:  # EIO: no slave side open (cannot happen while we hold one)
                    break
                if not data:
                    break
                n += len(data)
                self.received += data
            self.bytes_received_from_sniffer += n
        return n

    def play(
        self,
        frames: Iterable[WireFrame],
        speed: float = 1.0,
        stop_event: threading.Event | None = None,
    ) -> PlayStats:
        """Write frames at their bus times (scaled by 1/speed) relative to the first frame.

        Blocks until done; run it in a thread next to the reader.  A reader
        that stops reading makes writes wait (the pty buffer is finite), and
        stop_event still ends the play.
        """
        if speed <= 0:
            raise ValueError("speed must be > 0")
        start = time.monotonic_ns()
        first: int | None = None
        n_frames = n_bytes = 0
        for f in frames:
            if first is None:
                first = f.t_ns
            # an adapter hands a frame over once its last byte is in: write at its end
            due = start + int((f.t_end_ns - first) / speed)
            if not self.wait_until(due, stop_event):
                return PlayStats(n_frames, n_bytes, True)
            if not self.write_all(f.raw, stop_event):
                return PlayStats(n_frames, n_bytes, True)
            n_frames += 1
            n_bytes += len(f.raw)
        self.drain()
        return PlayStats(n_frames, n_bytes, False)

    def wait_until(self, due_ns: int, stop_event: threading.Event | None) -> bool:
        while True:
            if stop_event is not None and stop_event.is_set():
                return False
            left = due_ns - time.monotonic_ns()
            if left <= 0:
                return True
            # sleep on the master fd: wakes early to drain what the sniffer writes
            r, _, _ = select.select([self.master_fd], [], [], min(left / 1e9, _POLL_S))
            if r:
                self.drain()

    def write_all(self, data: bytes, stop_event: threading.Event | None) -> bool:
        view = memoryview(data)
        while view:
            if stop_event is not None and stop_event.is_set():
                return False
            try:
                k = os.write(self.master_fd, view)
                view = view[k:]
            except (BlockingIOError, InterruptedError):
                r, _, _ = select.select([self.master_fd], [self.master_fd], [], _POLL_S)
                if r:
                    self.drain()
        return True

    def close(self) -> None:
        if self._closed:
            return
        self.drain()
        with self._lock:
            self._closed = True
            for fd in (self.master_fd, self.slave_fd):
                try:
                    os.close(fd)
                except OSError:
                    pass


MASTER_ROLES = ("request", "broadcast")  # WireFrame.role of what the master sends


def play_tap(master: PtyBus, slaves: PtyBus, frames: Iterable[WireFrame], speed: float = 1.0,
             stop_event: threading.Event | None = None) -> tuple[PlayStats, PlayStats]:
    """One link's traffic on two ptys, as two receive-only adapters on a 4-wire link get it: what the
    master sends (requests, broadcasts) on `master`, what the slaves send (answers, noise) on `slaves`;
    each frame at its bus time (scaled by 1/speed), from one thread, so a request is written before its
    answer.  Returns what each pty carried."""
    if speed <= 0:
        raise ValueError("speed must be > 0")
    start = time.monotonic_ns()
    first: int | None = None
    counts = {id(master): [0, 0], id(slaves): [0, 0]}
    stopped = False
    for f in frames:
        if first is None:
            first = f.t_ns
        bus = master if f.role in MASTER_ROLES else slaves
        due = start + int((f.t_end_ns - first) / speed)
        if not bus.wait_until(due, stop_event) or not bus.write_all(f.raw, stop_event):
            stopped = True
            break
        counts[id(bus)][0] += 1
        counts[id(bus)][1] += len(f.raw)
    master.drain()
    slaves.drain()
    return (PlayStats(*counts[id(master)], stopped), PlayStats(*counts[id(slaves)], stopped))
