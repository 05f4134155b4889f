"""The timeline of writes and faults: what the master changed, and when a drive tripped, as events.

A write is a request that carries values for a register table (a Modbus 05/06/0F/10/17
or a PD-series write: its points are the values sent), with its outcome from its answer:
confirmed, an exception (named), no answer, or broadcast (unit 0: none expected).  The
same write repeated by a unit (the same bytes, one after the other) is one event with a
count, a first and a last time and its outcomes counted: a PLC writing its speed setpoint
every cycle is one line, not thousands.

A fault (or alarm) is what the drive's model reports in an answer (`model.fault`,
`model.alarm`).  A drive reports a fault in every answer to the poll that reads it, so
one fault is one episode: from the first answer that reports it to the last, ended by an
answer to the same poll (the same request type) that no longer does.

Bounded: the first HEAD events and the last TAIL are kept, the ones between counted.  In a capture
of several links a unit is its link's (`frame.unit_key`, shown "LINK:UNIT").
"""

from __future__ import annotations

from collections import Counter, deque

from decoders.registry import code_book
from sniffer.frame import unit_key
from sniffer.analysis.flags import FAULT_CODES
from sniffer.protocols import of_frame
from sniffer.analysis.diff import request_key

HEAD = 1000
TAIL = 1000
RECENT = 256  # requests remembered for their answers
TEXT = 300  # characters of a summary kept
_CATEGORY = code_book().categories  # code -> what it counts as ("fault", "alarm", ...)


class Timeline:
    """Writes and fault episodes (see the module doc); feed frames in order with `frame`."""

    def __init__(self, head: int = HEAD, tail: int = TAIL) -> None:
        self.head: list[dict] = []
        self.tail: deque = deque(maxlen=tail)
        self.head_max = head
        self.dropped = 0
        self.counts: Counter = Counter()  # events by kind
        self._requests: dict[int, tuple] = {}  # response index -> (request key, write event or None)
        self._last_write: dict[tuple, dict] = {}  # (link, unit) -> its latest write event
        self._open: dict[tuple, dict] = {}  # (link, unit, code, detail) -> the fault episode going on

    def _emit(self, ev: dict) -> None:
        self.counts[ev["kind"]] += 1
        if len(self.head) < self.head_max:
            self.head.append(ev)
            return
        if len(self.tail) == self.tail.maxlen:
            self.dropped += 1
        self.tail.append(ev)

    def new_capture(self) -> None:
        """Events do not run on from one capture into the next."""
        self._requests.clear()
        self._last_write.clear()
        self._open.clear()

    def frame(self, f, capture: int = 0) -> bool:
        """Take one frame; True when it is a write request."""
        if f.unit is None or f.crc_ok is False:
            return False
        if f.role == "request":
            return self._request(f, capture)
        if f.role == "response":
            self._response(f, capture)
        return False

    def _request(self, f, capture: int) -> bool:
        ev = None
        proto = of_frame(f.protocol)
        if proto is not None and f.points and proto.table_of(f.function) is not None:
            ev = self._write(f, capture)
            outcome = None
            if f.pair is None:
                outcome = "broadcast" if f.unit == 0 else "no answer"
            if outcome is not None:
                ev["outcomes"][outcome] = ev["outcomes"].get(outcome, 0) + 1
        if f.pair is not None:
            req = self._requests
            req[f.pair] = ((f.link, *request_key(f)), ev)
            if len(req) > RECENT:
                del req[next(iter(req))]
        return ev is not None

    def _write(self, f, capture: int) -> dict:
        raw = f.adu or f.raw
        uk = (f.link, f.unit)
        last = self._last_write.get(uk)
        if last is not None and last["_raw"] == raw:
            last["n"] += 1
            last["t_end"] = f.t_ns
            return last
        ev = {"kind": "write", "unit": str(unit_key(f)), "t": f.t_ns, "t_end": f.t_ns, "n": 1, "text": f.summary[:TEXT],
              "frame": f.index, "capture": capture, "outcomes": {}, "_raw": raw}
        self._last_write[uk] = ev
        self._emit(ev)
        return ev

    def _response(self, f, capture: int) -> None:
        key, write = self._requests.pop(f.index, (None, None))
        if write is not None:
            outcome = "exception" if f.exception else "confirmed"
            if f.exception:
                outcome = f"exception {int(f.exception.get('code') or 0):02X}H {f.exception.get('name') or ''}".strip()
            write["outcomes"][outcome] = write["outcomes"].get(outcome, 0) + 1
        reported = set()
        for a in f.annotations:
            if a.code in FAULT_CODES:
                k = (f.link, f.unit, a.code, a.detail)
                reported.add(k)
                ev = self._open.get(k)
                if ev is None:
                    kind = _CATEGORY[a.code]  # "fault" or "alarm" (sniffer.codes' categories)
                    ev = self._open[k] = {"kind": kind, "unit": str(unit_key(f)), "t": f.t_ns, "t_end": f.t_ns,
                                          "n": 1, "text": a.detail[:TEXT], "frame": f.index, "capture": capture,
                                          "_key": key}
                    self._emit(ev)
                else:
                    ev["n"] += 1
                    ev["t_end"] = f.t_ns
        if key is not None and self._open:  # the same poll answered without a fault it reported: it ended
            uk = (f.link, f.unit)
            for k in [k for k, ev in self._open.items() if k[:2] == uk and ev["_key"] == key and k not in reported]:
                del self._open[k]

    def events(self) -> list[dict]:
        """The kept events, in time order, with times in ns (the report turns them into seconds)."""
        out = []
        for ev in [*self.head, *self.tail]:
            out.append({k: v for k, v in ev.items() if not k.startswith("_")})
        return out
