"""The coordinator: hands parts of the capture to worker processes and takes them back in order.

    engine = Engine(spec, session, plans, jobs=4)     # session: opened (settings resolved), not run
    for part in engine.parts():                        # in capture order, each checked
        part.pieces                                     # one per plan: what its sink writes of the part

Events (sniffer.parallel.events).  A finished MCAP file is read by the workers
themselves, each its own part's chunks (Indexed); any other source is read here and
its events packed into the tasks (Stream).  A task has `part_events` events from its
nominal start, `warm_events` before it (the warm-up) and up to `over_events` after
its nominal end (where its closing quiet point is looked for).  At most `jobs` + 1
tasks wait for a worker, and pieces wait for their turn only while the parts before
them are in work: memory stays flat.

Checking (sniffer.parallel.truth).  A part is decoded from the latest state known
for certain when it was handed out.  When its turn comes it is checked against the
truth at its cut; if it fails (the units were still being named, a register that
scales others changed, its warm-up did not reach the state the part before ended
with), the coordinator decodes it again itself from the exact state (a worker may
be waiting for its number, so none is free to take it), warming up from the
accepted start of the part before.  A part with no quiet point to end at in its
events (a line that is never quiet: every request unanswered, endless noise)
ends the parallel run: the coordinator decodes the rest in order, in its own
process, from that part's cut (`_tail`).  An indexed file a part cannot read by
number (a damaged chunk) is read here from then on: the parts after it are made
again from the Stream.

Numbering.  A part's frames are numbered from 0 until it is checked: its first
number is the sum of the frames before it, sent back as "base"; then the worker
renumbers, encodes, and sends the pieces.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import wait

from sniffer.parallel.events import Indexed, NotIndexed, RawRange, Stream
from sniffer.parallel.part import Counted, Runner, Task, encode, run_part
from sniffer.parallel.truth import Truth
from sniffer.parallel.worker import recv, send, serve
from sniffer.processes.parent_death import worker_args

PART_EVENTS = 1024  # a part's frames and pieces are held whole (worker and coordinator): 4096 held 100+ MB
WARM_EVENTS = 64
OVER_EVENTS = 2048
READ_BATCH = 512  # events read between two looks at the workers' pipes


class WorkerError(RuntimeError):
    """A worker failed (a bug, or it was killed): the run stops."""


@dataclass
class Part:
    """A part in capture order, checked: its counts and one piece per plan."""

    counted: Counted
    pieces: list


class _Worker:
    def __init__(self, ctx, setup: bytes) -> None:
        self.conn, child = ctx.Pipe(duplex=True)
        self.proc = ctx.Process(target=serve, args=(child, *worker_args()), daemon=True, name="sniffer-part")
        self.proc.start()
        child.close()
        self.conn.send_bytes(setup)
        self.part: int | None = None  # the part it works on (None: free)
        self.stale = False  # its part was made again (its answer is dropped)


def event_store(session, on_event=None):
    """Indexed for a finished MCAP file nobody watches the reading of (a progress bar), else Stream."""
    from sniffer.sources.files import FileSource

    source = session.source
    if on_event is None and isinstance(source, FileSource) and source.format == "mcap" \
            and not session.info.extra.get("mcap_unfinished"):
        from sniffer.formats.mcap.ranges import raw_index

        index = raw_index(source.path)
        if index is not None:
            return Indexed(index)
    return Stream(source.events(), on_event)


class Engine:
    def __init__(self, spec, session, plans, jobs: int, *, part_events: int | None = None,
                 warm_events: int | None = None, over_events: int | None = None) -> None:
        self.spec, self.session, self.plans = spec, session, list(plans)
        self.jobs = max(1, jobs)
        self.part_events = part_events or PART_EVENTS
        self.warm = WARM_EVENTS if warm_events is None else warm_events
        self.over = over_events or OVER_EVENTS
        p = session.pipeline
        self.truth = Truth(dict(getattr(p, "registries", None) or {"": session.registry}))
        self.info = session.info
        self.redone = 0  # parts the coordinator decoded again
        self.tail = False  # the rest was decoded in order (no quiet point to cut at)
        self.switched = False  # an indexed file turned out not to be (read here from then on)
        self.on_event = None  # called with each event read (a progress bar)
        self._store = None
        self._workers: list[_Worker] = []
        self._next_start: int | None = 0  # the nominal start of the next task (None: the last is made)
        self._made = 0
        self._tasks: deque[Task] = deque()  # made, not handed out
        self._given: dict[int, Task] = {}  # part -> its task, until checked
        self._counted: dict[int, tuple] = {}  # part -> (Counted, its worker): decoded, not checked
        self._results: dict[int, tuple] = {}  # part -> (Counted, pieces or None): checked, not handed on
        self._check = 0  # the next part to check
        self._merge = 0  # the next part to hand on
        self._started: dict[int, int] = {}  # part -> the first event its accepted run was fed

    # ------------------------------------------------------------ tasks
    def _make_tasks(self) -> None:
        """Tasks for what has been read: a part once its overrun is read too (or the source ended)."""
        store = self._store
        while self._next_start is not None and len(self._tasks) <= self.jobs:
            start = self._next_start
            end = start + self.part_events
            if not store.ended and store.read < end + self.over:
                store.read_some(min(end + self.over - store.read, READ_BATCH))
                if not store.ended:
                    return  # a look at the pipes first
            last = store.ended and store.read <= end + self.over
            hi = store.read if last else end + self.over
            lo = max(0, start - self.warm)
            self._tasks.append(Task(self._made, store.slice(lo, hi), lo, start, None if last else end, {},
                                    error=store.error if last else None))
            self._made += 1
            self._next_start = None if last else end

    def _trim(self) -> None:
        """Drop the events no task can need again (a redo warms up from the accepted start of the part
        before it)."""
        keep = self._started.get(self._check - 1, 0)
        for t in (*self._tasks, *self._given.values()):
            keep = min(keep, t.first)
        self._store.trim(keep)

    def _switch(self, k: int) -> None:
        """Part k's events cannot be read by number: read the capture here from the accepted start of the part
        before it on (the reader's numbers are the messages' up to there), and make the parts from k again."""
        first = self._started.get(k - 1, 0)
        keep = min(first, max(0, self.truth.cut - self.warm))
        self._store = Stream(self.session.source.events(), self.on_event, skip=keep)
        self.switched = True
        for w in self._workers:
            if w.part is not None and w.part >= k:
                w.stale = True
        self._tasks.clear()
        for part in [p for p in self._given if p >= k]:
            del self._given[part]
        for part in [p for p in self._counted if p >= k]:
            c, w = self._counted.pop(part)
            if w is not None and not isinstance(c, str):
                send(w.conn, ("drop",))
                w.part, w.stale = None, False
        self._made, self._next_start = k, self.truth.cut

    # ------------------------------------------------------------ the run
    def parts(self):
        """Every part, in capture order, checked (see the module doc)."""
        self._store = event_store(self.session, self.on_event)
        try:
            yield from self._run()
        finally:
            self.close()

    def _run(self):
        ctx = multiprocessing.get_context("fork" if hasattr(os, "fork") else "spawn")
        setup = pickle.dumps(("setup", self.spec, self.info, self.plans), protocol=pickle.HIGHEST_PROTOCOL)
        while True:
            self._make_tasks()
            if not self._workers and self._next_start is None and len(self._tasks) == 1 and not self._given:
                got = self._alone(self._tasks.popleft())  # a capture of one part: no process to start
                if got is not None:
                    yield got
                    return
                continue
            self._trim()
            for w in self._workers:
                if w.part is None and self._tasks:
                    self._give(w, self._tasks.popleft())
            while self._tasks and len(self._workers) < self.jobs:
                w = _Worker(ctx, setup)
                self._workers.append(w)
                self._give(w, self._tasks.popleft())
            while (got := self._turn()) is not None:
                if got == "tail":
                    yield from self._tail()
                    return
                yield got
                if got.counted.end is None:
                    return
            busy = [w.conn for w in self._workers if w.part is not None]
            store = self._store
            reading = self._next_start is not None and not store.ended and len(self._tasks) <= self.jobs
            if not busy and not reading and not self._tasks and self._next_start is None:
                raise WorkerError("the parts ran out before the capture's end")  # a bug: nothing left to wait for
            for conn in wait(busy, timeout=0 if reading else None) if busy else ():
                self._message(next(w for w in self._workers if w.conn is conn))

    def _alone(self, task: Task) -> Part | None:
        task.guess = self.truth.guess()
        self._given[task.part] = task
        try:
            result = run_part(self.spec, self.info, self.plans, task)
        except NotIndexed:
            self._switch(task.part)
            return None
        base = self.truth.base
        why = self.truth.take(result.counted)
        if why is not None:
            raise WorkerError(f"a capture of one part decoded from its start differs: {why}")
        self._taken(task.part)
        return Part(result.counted, result.pieces(base))

    def _give(self, w: _Worker, task: Task) -> None:
        task.guess = self.truth.guess()
        w.part = task.part
        self._given[task.part] = task
        send(w.conn, ("part", task))
        task.guess = {}

    def _message(self, w: _Worker) -> None:
        try:
            msg = recv(w.conn)
        except (EOFError, OSError):
            raise WorkerError(f"a worker process ended unexpectedly (exit code {w.proc.exitcode})") from None
        if msg[0] == "error":
            raise WorkerError(msg[1])
        if msg[0] == "counted":
            c = msg[1]
            holds = c.cut is not None and not c.no_end
            if w.stale:  # made again from the Stream: this answer is for nothing
                if holds:
                    send(w.conn, ("drop",))
                w.part, w.stale = None, False
                return
            self._counted[c.part] = (c, w if holds else None)
            if not holds:
                w.part = None
        elif msg[0] == "pieces":
            c, _ = self._results[msg[1]]
            self._results[msg[1]] = (c, msg[2])
            w.part = None

    def _turn(self):
        """Take what can be taken; the next part in order if its pieces are here, "tail", or None."""
        # a part taken with no end closed the capture (its source's error): the parts after it are nothing
        while self.truth.cut is not None and (got := self._counted.get(self._check)) is not None:
            k = self._check
            c, w = got
            if c == "tail":  # no quiet point follows this part's cut: the rest in order, once it is its turn
                if self._merge == k:
                    return "tail"
                break
            del self._counted[k]
            if w is not None:
                base = self.truth.base
                if self.truth.take(c) is None:
                    self._results[k] = (c, None)
                    send(w.conn, ("base", base))
                    self._taken(k)
                    continue
                send(w.conn, ("drop",))  # decoded from a wrong guess
                w.part = None
            redo = self._redo(k)
            if redo is None:  # made again from the Stream
                break
            if redo[0] == "tail":
                self._counted[k] = ("tail", None)
                continue
            self._results[k] = redo
        k = self._merge
        got = self._results.get(k)
        if got is None or got[1] is None:
            return None
        del self._results[k]
        self._merge = k + 1
        return Part(got[0], got[1])

    def _taken(self, k: int) -> None:
        self._started[k] = self._given.pop(k).first
        self._check = k + 1

    def _redo(self, k: int):
        """Part k again, in this process, from the truth at its cut (warming up from where the part before
        started, so the pipeline reaches the cut as the whole capture does): (counted, pieces); ("tail", c)
        if it has no quiet point to end at in the events read for it; None if its events cannot be read by
        number (the parts from k on are made again from the Stream)."""
        task = self._given[k]
        first = self._started.get(k - 1, 0)
        redo = Task(k, self._store.slice(first, task.first + len(task.events)), first, task.start, task.end,
                    self.truth.guess(), exact=(self.truth.cut, self.truth.guess()), error=task.error)
        try:
            result = run_part(self.spec, self.info, self.plans, redo)
        except NotIndexed:
            self._switch(k)
            return None
        c = result.counted
        if c.no_end:
            return "tail", c
        base = self.truth.base
        why = self.truth.take(c)
        if why is not None:
            raise WorkerError(f"part {k} decoded again from the exact state still differs: {why}")
        self.redone += 1
        self._given[k] = redo
        self._taken(k)
        return c, result.pieces(base)

    def _rest(self, start: int):
        """The events from number `start` on, in order (an indexed file that cannot be read so from some point
        on is read from the source there)."""
        store, pos = self._store, start
        if isinstance(store, Indexed):
            try:
                for lo in range(start, store.read, self.part_events):
                    hi = min(lo + self.part_events, store.read)
                    yield from RawRange(store.index, lo, hi).load()
                    pos = hi
                return
            except NotIndexed:
                self._store = store = Stream(self.session.source.events(), self.on_event, skip=pos)
                self.switched = True
        yield from store.rest(pos)

    def _tail(self):
        """From the cut of the part being checked to the end, in order, in this process (no quiet point left
        to cut at): the workers stop; the rest streams in pieces of about `part_events` events."""
        k = self._check
        self.close()
        self.tail = True
        first = self._started.get(k - 1, 0)
        r = Runner(self.spec, self.info, self.plans, self.truth.guess())
        p = r.pipeline
        events = self._rest(first)
        g = first
        pending = None
        for ev in events:
            if g == self.truth.cut:
                pending = ev
                break
            p.feed(ev)
            g += 1
        if pending is not None:
            r.quiet_before(pending)  # as the part before ended there
        c = Counted(k, None)
        r.cut(c, g, self.truth.guess())
        delta, first_piece, done = self.truth.base - r.offset, self.truth.base == 0, 0
        error = None
        for ev in self._chain(pending, events):
            try:
                p.feed(ev)
            except Exception as e:  # noqa: BLE001 - a CaptureError: as a session, the capture ends here
                from sniffer.events import CaptureError

                if not isinstance(e, CaptureError):
                    raise
                error = str(e)
                break
            g += 1
            if len(r.rec.calls) >= self.part_events:
                calls = r.take()
                n = sum(1 for x in calls if type(x) is not tuple)
                done += n
                yield Part(Counted(k, g, end=g, frames=n), encode(r.info, self.plans, calls, delta, first_piece))
                first_piece = False
        p.flush()
        c.error = error or self._store.error
        r.end(c, None)
        c.frames -= done
        for link, reg in self.truth.regs.items():  # the naming the capture ends with (the report reads it)
            reg.restore({"states": {}, **r.regs[link].identity_state()})
        yield Part(c, encode(r.info, self.plans, r.take(), delta, first_piece))

    @staticmethod
    def _chain(first, rest):
        if first is not None:
            yield first
        yield from rest

    def close(self) -> None:
        for w in self._workers:
            try:
                send(w.conn, ("stop",))
            except OSError:
                pass
        for w in self._workers:
            w.proc.join(timeout=2)
            if w.proc.is_alive():
                w.proc.terminate()
                w.proc.join(timeout=2)
            w.conn.close()
        self._workers = []


__all__ = ["Engine", "Part", "WorkerError", "event_store"]
