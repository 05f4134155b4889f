"""One part of a capture, decoded alone: what a worker process (and the coordinator, for a part it redoes) runs.

    result = run_part(spec, info, plans, task)        # decode: the part's frames held, numbered from 0
    result.counted                                    # what the coordinator checks the part by
    pieces = result.pieces(base)                      # renumbered to the whole capture's numbers, then encoded

A part starts at a quiet point: between two events where nothing is pending
(`Pipeline.settled() == 2`: no byte in a framer, no request waiting).  The
coordinator names a nominal start (an event number); the part runner feeds the
events before it as a warm-up (a fresh pipeline learns the line: the last frame's
end, a broadcast just before), then takes the first quiet point at or after the
nominal start as its cut, and runs to the first quiet point at or after the nominal
end, where the next part cuts.  Two runs whose states agree at the nominal start
find the same cut, so the part before and this one meet exactly.

What the part reports (`Counted`), for the coordinator to hold it against the part
before: the cut and the pipeline's state there (`Pipeline.cut_state`), what names
the units there (`DecoderRegistry.naming`), every read of a unit's memory the
part did not write first (its value came from a guess: `DecoderRegistry.track`),
every frame the units' identifier observed and the notes it gave, and at its end
the pipeline's state, what it wrote and how many frames it made.  A task
may also be exact (`Task.exact`): the cut and the decoders' state at it are known
(a part redone after a wrong guess), and the warm-up runs up to that cut.

`Runner` is the same run one step at a time, for the coordinator's streaming tail
(a capture with no quiet point left: the rest decoded in order, in its process).

A task's events are the packed events the coordinator read, or a range of an
indexed file the runner reads itself (sniffer.parallel.events).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sniffer.events import CaptureError, CaptureInfo
from sniffer.parallel.events import events_of, unpack
from sniffer.sinks.base import Sink


@dataclass
class Task:
    """A part to decode: `events` (packed, or a RawRange) are events first, first + 1, ...; the part cuts at the
    first quiet point at or after event `start` and ends at the first at or after `end` (None: at the end of the
    capture, where everything pending is flushed).  `guess`: {link: registry snapshot} to decode with.
    `exact`: (cut, {link: registry snapshot}) when the cut and the decoders' state there are known."""

    part: int
    events: list
    first: int
    start: int
    end: int | None
    guess: dict
    exact: tuple | None = None
    error: str | None = None  # the source failed after the last event: the part ends there, as the capture


@dataclass
class Counted:
    """What a decoded part says about itself (the coordinator checks it against the part before)."""

    part: int
    cut: int | None  # the event the part starts at (None: no quiet point found)
    state: tuple | None = None  # Pipeline.cut_state at the cut
    identity: dict = field(default_factory=dict)  # link -> DecoderRegistry.naming() at the cut
    reads: dict = field(default_factory=dict)  # link -> {(unit, table, key): (known, value)}
    end: int | None = None  # the event the next part starts at (None: the capture ended in this part)
    end_state: tuple | None = None
    writes: dict = field(default_factory=dict)  # link -> {unit: {table: {key: value}}}
    observed: dict = field(default_factory=dict)  # link -> what its identifier observed (registry.replay)
    frames: int = 0
    bytes_in: int = 0
    noise_bytes: int = 0
    error: str | None = None  # the capture ends in this part with this error (a CaptureError, as a session)
    why: str = ""  # why no cut was found
    no_end: bool = False  # the part found its cut but no quiet point to end at in the events it was given


class _Recorder(Sink):
    """The pipeline's one sink in a part: keeps the part's calls, in order, once recording.

    Frames handed on while `deferring` (closed by the silence before the next event, ahead of it:
    Pipeline.close_before) wait until that event's raw call, where one process hands them on; still
    waiting at the part's end, they close its calls as ("after", frames): a writer of raw events puts
    them after the next part's first event."""

    def __init__(self, raw: bool) -> None:
        self.on = False
        self.want_raw = raw
        self.deferring = False
        self.calls: list = []  # Frame, ("raw", event), or ("after", [Frame, ...]) last
        self.deferred: list = []

    def raw(self, event) -> None:
        if self.on:
            if self.want_raw:
                self.calls.append(("raw", event))
            if self.deferred:
                self.calls += self.deferred
        self.deferred = []

    def frame(self, frame) -> None:
        if self.on:
            if self.deferring:
                self.deferred.append(frame)
            else:
                self.calls.append(frame)

    def ending(self) -> None:
        """The part ends: frames still deferred go last, marked."""
        if self.on and self.deferred:
            self.calls.append(("after", self.deferred))
        self.deferred = []


def encode(info: CaptureInfo, plans, calls: list, delta: int, first_part: bool) -> list:
    """The plans' pieces of a part's calls, its frames moved `delta` numbers on (one piece per plan)."""
    from sniffer.capture.pairer import renumber

    renumber([f for c in calls for f in (c[1] if type(c) is tuple and c[0] == "after" else
                                         () if type(c) is tuple else (c,))], delta)
    sinks = [plan.part_sink(info, first_part) for plan in plans]
    for s in sinks:
        s.start(info)
    raws = [s.raw for s in sinks if getattr(s, "wants_raw", False)]
    feeds = [s.frame for s in sinks]
    for c in calls:
        if type(c) is not tuple:
            for feed in feeds:
                feed(c)
        elif c[0] == "raw":
            for raw in raws:
                raw(c[1])
        else:  # ("after", frames): they follow the next part's first event
            for s in sinks:
                after = getattr(s, "after", None)
                for f in c[1]:
                    (after or s.frame)(f)
    out = []
    for s in sinks:
        s.close()
        out.append(s.piece())
    return out


class Runner:
    """A pipeline for a part: warm up, cut, then record (see the module doc)."""

    def __init__(self, spec, info: CaptureInfo, plans, guess: dict) -> None:
        from sniffer.capture.session import EventSource, Session

        self.plans = plans
        self.rec = _Recorder(any(getattr(p, "wants_raw", False) for p in plans))
        session = Session(spec, EventSource(info, ()), [self.rec])
        session.open()
        self.info = session.info
        self.pipeline = session.pipeline
        self.regs = dict(getattr(self.pipeline, "registries", None) or {"": session.registry})
        for link, reg in self.regs.items():
            reg.restore(guess[link])
        self.offset = 0
        self._bytes0 = self._noise0 = 0

    def cut(self, counted: Counted, event: int, exact_state: dict | None = None) -> None:
        """The part starts here (before event number `event`): note the state, start recording."""
        p = self.pipeline
        counted.cut = event
        self.offset = p.numbered()
        counted.state = p.cut_state(self.offset)
        if exact_state is not None:
            for link, reg in self.regs.items():
                reg.restore(exact_state[link])
        counted.identity = {link: reg.naming() for link, reg in self.regs.items()}
        for reg in self.regs.values():
            reg.track()
        self.rec.on = True
        self._bytes0, self._noise0 = p.bytes_in, p.noise_bytes

    def quiet_before(self, ev) -> bool:
        """Is the point before event `ev` quiet (nothing pending), once the silence before it has closed
        what it closes (Pipeline.close_before; a one-line capture: the links' merge waits on its own)?"""
        p = self.pipeline
        if p.settled() == 2:
            return True
        if self.regs.keys() != {""}:
            return False
        self.rec.deferring = True
        try:
            p.close_before(ev)
        finally:
            self.rec.deferring = False
        return p.settled() == 2

    def end(self, counted: Counted, event: int | None) -> None:
        """The part ends before event number `event` (None: the capture ended, everything flushed)."""
        p = self.pipeline
        counted.end = event
        self.rec.ending()
        if event is not None:
            counted.end_state = p.cut_state()
        counted.frames = p.numbered() - self.offset
        counted.bytes_in, counted.noise_bytes = p.bytes_in - self._bytes0, p.noise_bytes - self._noise0
        for link, reg in self.regs.items():
            counted.reads[link], counted.writes[link], counted.observed[link] = reg.tracked()

    def take(self) -> list:
        """The calls recorded so far (they leave the runner)."""
        calls, self.rec.calls = self.rec.calls, []
        return calls


class PartResult:
    """A decoded part: `counted`, and `pieces(base)` (the plans' outputs, frames numbered from `base`)."""

    def __init__(self, counted: Counted, info: CaptureInfo | None = None, plans=(), calls=(), offset: int = 0) -> None:
        self.counted = counted
        self._info, self._plans, self._calls, self._offset = info, plans, list(calls), offset

    def pieces(self, base: int) -> list:
        calls, self._calls = self._calls, []
        return encode(self._info, self._plans, calls, base - self._offset, base == 0)


def run_part(spec, info: CaptureInfo, plans, task: Task) -> PartResult:
    """Decode one part (see the module doc); the pieces wait for the part's first frame number.  NotIndexed
    (sniffer.parallel.events) if its events are an indexed file's that cannot be read by number."""
    events = events_of(task.events)
    r = Runner(spec, info, plans, task.guess)
    p = r.pipeline
    n = len(events)
    k = 0  # events[k] is event number task.first + k
    first, start = task.first, task.start
    counted = Counted(task.part, None)
    exact_cut = task.exact[0] if task.exact else None
    try:
        # the warm-up, then the cut: the first quiet point at or after `start` (or the known one)
        while k < n and first + k < (start if exact_cut is None else exact_cut):
            p.feed(unpack(events[k]))
            k += 1
        if exact_cut is not None:
            if k < n:
                r.quiet_before(unpack(events[k]))  # as the part before ended there
        else:
            while k >= n or not r.quiet_before(ev := unpack(events[k])):
                if k >= n:
                    if task.end is None and p.settled() == 2:
                        break  # the capture ends here with nothing pending (a line with no traffic): its end is quiet
                    counted.why = "no quiet point in the events it was given"
                    return PartResult(counted)
                p.feed(ev)
                k += 1
    except CaptureError as e:
        counted.why = f"error in the warm-up: {e}"
        return PartResult(counted)
    r.cut(counted, first + k, task.exact[1] if task.exact else None)
    end = task.end
    try:
        while True:
            if k >= n:
                if end is not None:
                    counted.no_end = True
                    return PartResult(counted)
                counted.error = task.error
                p.flush()
                r.end(counted, None)
                break
            ev = unpack(events[k])
            if end is not None and first + k >= end and r.quiet_before(ev):
                r.end(counted, first + k)
                break
            p.feed(ev)
            k += 1
    except CaptureError as e:  # as a session: what is pending is flushed and the capture ends here
        counted.error = str(e)
        p.flush()
        r.end(counted, None)
    return PartResult(counted, r.info, plans, r.take(), r.offset)
