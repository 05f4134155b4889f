"""Where live readers hand over their events (a Hub), and what they end with: shared by the serial reader
(serial_live.py, termios) and the gateway reader (pyserial_line.py, pyserial alone), so the second needs no
POSIX terminal module."""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterator

from sniffer.events import CaptureError, Chunk, Gap, Tick


class PortLostError(CaptureError):
    """The port went away during a capture and reconnect was off."""


class ReaderEnd:
    """A reader's last item: its source (whose `_error`, if any, the consumer raises)."""

    __slots__ = ("source",)

    def __init__(self, source) -> None:
        self.source = source


class Hub:
    """Where reader threads hand over their events: one queue, in time order (serial_live.py says why).

    A reader holds `clock` from taking an event's time until the event is queued.  Ticks of one
    link that the consumer has not taken yet are kept as the latest only.
    """

    def __init__(self) -> None:
        self.clock = threading.Lock()
        self._queue: deque = deque()
        self._cond = threading.Condition()

    def push(self, item) -> None:
        with self._cond:
            q = self._queue
            if type(item) is Tick and q and type(q[-1]) is Tick and q[-1].link == item.link:
                q[-1] = item  # consumer is behind: only the latest silence matters
            else:
                q.append(item)
            self._cond.notify()

    def lost(self, reader) -> None:
        """`reader`'s port went away (its lost_since_ns set) or came back (None): nothing here (a reader
        process tells its capture, processes/reader.py)."""

    def events(self, readers: int) -> Iterator[Chunk | Tick | Gap]:
        """Every queued event until `readers` readers have ended; a reader's error is raised."""
        while readers:
            with self._cond:
                while not self._queue:
                    self._cond.wait(0.1)
                item = self._queue.popleft()
            if type(item) is ReaderEnd:
                readers -= 1
                if item.source._error is not None:
                    raise item.source._error
                continue
            yield item
