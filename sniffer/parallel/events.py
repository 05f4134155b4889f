"""Where the parts' events come from: read here and sent (Stream), or read by each worker itself (Indexed).

Either way an event has a number, its place in the capture's order, and a task names
its events by number (first .. first + n).

* Stream: the coordinator reads the source (a byte CSV, a pcap, a sigrok file, a
  rotated capture's folder, an MCAP it cannot index) and packs the events into the
  tasks.  One reader: damage, holes and gaps are found once, as one process finds
  them.  It holds the events from the oldest any task may need on (`trim`).
* Indexed: a finished MCAP file (sniffer.formats.mcap.ranges): its /raw messages are
  numbered, and a task carries only a RawRange, which its worker reads from the
  chunks.  The coordinator reads nothing but the file's summary.  A chunk that fails
  its CRC, or an event of a kind this sniffer does not know, is not for a part to
  decide (the reader skips the one and says so, and skips the other): `load` raises
  NotIndexed, and the coordinator reads the rest itself from that part's cut on.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from itertools import islice

from sniffer.events import CaptureError, Chunk, Gap, Tick, read_fields


def pack(ev) -> tuple:
    """An event as a tuple of plain values (`unpack` gives it back)."""
    kind = type(ev)
    if kind is Chunk:
        return (0, *read_fields(ev))
    if kind is Tick:
        return (1, ev.t_ns, ev.link)
    return (2, ev.t_ns, ev.t_end_ns, ev.reason, ev.link, ev.state)


def unpack(t):
    """An event back from `pack` (an event already is one)."""
    if type(t) is not tuple:
        return t
    kind = t[0]
    if kind == 0:
        return Chunk(*t[1:])
    if kind == 1:
        return Tick(t[1], t[2])
    return Gap(t[1], t[2], t[3], t[4], t[5])


class NotIndexed(Exception):
    """Events of an indexed file a part cannot take by number (a damaged chunk, a kind unknown here)."""


@dataclass(frozen=True)
class RawRange:
    """Events lo .. hi-1 of an indexed MCAP file, read where they are decoded."""

    index: object  # sniffer.formats.mcap.ranges.RawIndex
    lo: int
    hi: int

    def load(self) -> list:
        from sniffer.formats.mcap.format import decode_event
        from sniffer.formats.mcap.ranges import Damaged, read_raw

        try:
            datas = read_raw(self.index, self.lo, self.hi)
        except Damaged as e:
            raise NotIndexed(str(e)) from None
        out = []
        for data in datas:
            try:
                ev = decode_event(data)
            except (ValueError, KeyError, TypeError) as e:
                raise NotIndexed(f"a /raw message that does not read: {e}") from None
            if ev is None:
                raise NotIndexed("a /raw message of a kind this sniffer does not know")
            out.append(ev)
        return out

    def __len__(self) -> int:
        return self.hi - self.lo


def events_of(items) -> list:
    """A task's events: a RawRange read (NotIndexed), or the packed events it carries."""
    return items.load() if isinstance(items, RawRange) else items


class Stream:
    """The source's events read here; numbers from 0 (the first `skip` read and dropped)."""

    def __init__(self, events, on_event=None, skip: int = 0) -> None:
        self._it = iter(events)
        self.on_event = on_event
        self._events: deque = deque()
        self.first = skip  # the number of self._events[0]
        self.read = 0
        self.ended = False
        self.error: str | None = None  # the source's error (it ended there)
        while self.read < skip and not self.ended:
            if self._next() is None:
                break
        self._events.clear()
        self.first = self.read

    def _next(self):
        try:
            ev = next(self._it, None)
        except CaptureError as e:  # as a session: everything read before is decoded, then it ends
            self.ended, self.error = True, str(e)
            return None
        if ev is None:
            self.ended = True
            return None
        self.read += 1
        if self.on_event is not None:
            self.on_event(ev)
        return ev

    def read_some(self, n: int) -> None:
        events = self._events
        for _ in range(n):
            if self.ended:
                return
            ev = self._next()
            if ev is not None:
                events.append(pack(ev))

    def slice(self, lo: int, hi: int) -> list:
        return list(islice(self._events, max(0, lo - self.first), max(0, hi - self.first)))

    def trim(self, keep: int) -> None:
        while self.first < keep and self._events:
            self._events.popleft()
            self.first += 1

    def rest(self, start: int):
        """Every event from number `start` on (the coordinator's tail), unpacked."""
        for t in self.slice(start, self.read):
            yield unpack(t)
        self._events.clear()
        while not self.ended:
            ev = self._next()
            if ev is not None:
                yield ev


class Indexed:
    """An indexed MCAP file's events: every number known at once, read by whoever needs them."""

    def __init__(self, index) -> None:
        self.index = index
        self.read = index.total
        self.first = 0
        self.ended = True
        self.error = None

    def read_some(self, n: int) -> None:
        pass

    def slice(self, lo: int, hi: int) -> RawRange:
        return RawRange(self.index, max(0, lo), min(hi, self.read))

    def trim(self, keep: int) -> None:
        pass

    def rest(self, start: int, step: int = 4096):
        for lo in range(start, self.read, step):
            yield from RawRange(self.index, lo, min(lo + step, self.read)).load()
