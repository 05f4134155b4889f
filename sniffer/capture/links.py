"""Several links on one timeline: one pipeline per link, one clock, one set of sinks, frames in time order.

A machine has two or three RS-485 links, or one 4-wire link tapped with two
receive-only adapters (--tap).  Each link is its own line: its own settings,
framer, pairer and decoders (a unit 1 on link A is not unit 1 on link B), so
a link's bytes never glue onto another's frames.  What they share:

* the clock: every event carries monotonic time (sources/serial_links.py stamps
  the reads of all ports under one lock, so the events come in time order);
* the frame numbers: one capture-wide sequence in time order, so `#N` and
  pairs name one frame;
* the sinks: one MCAP, one text/JSONL stream, one TUI.  Every event and frame
  carries its link's name (Chunk/Tick/Gap.link, Frame.link): the MCAP's
  /raw and /frames say which link (sniffer.formats.mcap.format), and a replay hands
  each link's events to that link's pipeline again, so it re-splits exactly.

The merge.  A link settles its frames at its own pace: a frame closes after
its line's silence (t3.5, and a USB read's slack), a request waits in the
pairer for its answer.  Handed on as each link settles them, the frames of
several links come out of time order.  So every frame passes two stages:

1. time order (`_release`): the frames a link's framer closed wait in that
   link's queue; the earliest head of all queues goes on once every other
   link has settled past its start (`_horizon`: nothing that link frames from
   now on can start earlier).  It is numbered there (numbers follow time)
   and goes to its own link's pairer and decoders;
2. number order: a pairer hands a request on with its answer (or at its
   timeout, or at the next request), so decoded frames wait until every lower
   number has gone on; the sinks get them in number order, which is time order.

A link's horizon is the start of its first queued frame, else of the bytes
its framer holds, else the capture's clock (the latest recorded event's time;
the source's events come in time order) less what a read's times may reach
back: per read, the framer's read slack (a read's bytes are timed back from
when it returned, and the framer assumes no read comes later than its slack);
per byte, nothing.

The hold bound (`hold_ns`).  A healthy link settles every frame within its
longest response timeout (a request waits that long for its answer, then a
tick settles it) plus its longest frame (MAX_LINE characters at its speed) and
the silence that closes it (t3.5 and the read slack).  A link that holds a
frame longer is stalled: its reader got no time, its port went away, its
events stopped in a file.  Waiting for it would freeze every other link's
frames and keep them in memory, so once the clock is `hold_ns` past the start
of the frame that waits, it goes on without the stalled link, which is no
longer waited for until its next event.  Its frames, when they come, go on at
once: after frames that are later than them (the one place where the output
leaves time order, and numbers go back).  hold_ns is the longest healthy wait
of any link, capped at MAX_HOLD_S: a response timeout of minutes would freeze
the live views that long.

Live and replay give the same frames in the same order: the merge looks only
at the events it records (a tick that changes nothing is not recorded and
does not move its clock), and a replay feeds exactly those again.

`LinkPipelines` is what sniffer.capture.session drives when the capture's
CaptureInfo lists links (`info.links`): the same feed / settled / flush /
close as a Pipeline.
"""

from __future__ import annotations

import copy

import heapq
from collections import deque

from decoders.carry import of_info, record

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.frame import CAN_REQ, CAN_RSP, Frame
from sniffer.framing.hexline import MAX_LINE
from sniffer.capture.pipeline import Pipeline, close_sinks
from sniffer.capture.settings import MASTER, SLAVES, Resolved
from sniffer.events import CaptureError

TAP_ROLES = {MASTER: CAN_REQ, SLAVES: CAN_RSP}  # the master's pair carries requests, the slaves' pair responses
MAX_HOLD_S = 10.0  # the longest the merge waits for a stalled link (see the module doc)


def link_names(info: CaptureInfo | None) -> list[str]:
    """The names of a capture's links, in order ([] for one line)."""
    return [str(x.get("name", "")) for x in (info.links if info is not None else ())]


def healthy_wait_ns(res: Resolved, read_slack_ns: int) -> int:
    """The longest a healthy link at `res` keeps a frame unsettled (the module doc's hold bound)."""
    line = res.line
    timeout_ms = max([res.timeout_ms, *res.unit_timeouts.values()])
    return int(timeout_ms * 1e6) + MAX_LINE * line.char_ns + line.t35_ns + read_slack_ns


class LinkPipelines:
    """One Pipeline per link of `info.links`, their frames merged into time order for the same sinks.

    `resolved` are the links' settings (name -> sniffer.capture.settings.Resolved);
    `registries` their decoder registries (each link decodes its own units);
    `hold_ns` the hold bound (module doc).
    """

    def __init__(self, info: CaptureInfo, resolved: dict[str, Resolved], sinks) -> None:
        """`resolved`: every link's settings (CaptureSpec.resolve_link), by name, as `info.links` lists them."""
        self.info = info
        self.sinks = list(sinks)
        self.resolved = resolved
        self.registries = {}
        self.pipelines: dict[str, Pipeline] = {}
        for entry in info.links:
            resolved[str(entry.get("name", ""))].record_link(entry)
        first = self.resolved[link_names(info)[0]]
        first.record_in(info)  # the capture's own line fields: its first link's (tools that read one line)
        for entry in info.links:
            name = str(entry["name"])
            res = self.resolved[name]
            registry = self.registries[name] = res.registry(of_info(info, name))
            self.pipelines[name] = Pipeline(  # no sinks of its own: its frames go through the merge
                info, res.line, registry, (), protocol=res.protocol.name, timeout_ms=res.timeout_ms,
                unit_timeouts=res.unit_timeouts or None, link=name,
                directions=TAP_ROLES if entry.get("tap") else None, start=False)
        self._names = list(self.pipelines)
        self._order = {name: k for k, name in enumerate(self._names)}
        self._queues: dict[str, deque] = {name: deque() for name in self._names}  # frames, ticks, gaps' states
        # how far back a link's next read may reach: per read until a link's reads show per-byte times
        self._slack = {name: p.framer.read_slack_ns for name, p in self.pipelines.items()}
        self._reach = dict(self._slack)
        self._stalled: set[str] = set()  # links the merge went on without (until their next event)
        self._ready: list = []  # (index, frame): paired and decoded, waiting for a lower number
        self._numbered = 0  # the next frame's number
        self._next_out = 0  # the lowest number not handed on yet
        self._clock: int | None = None
        self.hold_ns = min(int(MAX_HOLD_S * 1e9), max(healthy_wait_ns(self.resolved[name], self._slack[name])
                                                      for name in self._names))
        self.frames_out = 0
        record(info, self.decoder_state())  # what the capture starts with (its first part, every copy)
        for s in self.sinks:
            s.start(info)

    @property
    def bytes_in(self) -> int:
        return sum(p.bytes_in for p in self.pipelines.values())

    @property
    def noise_bytes(self) -> int:
        return sum(p.noise_bytes for p in self.pipelines.values())

    # ------------------------------------------------------------ input
    def feed(self, ev) -> list[Frame]:
        """Record `ev` (unless it is a tick that changes nothing) and return the frames it lets go, in order."""
        name = ev.link
        kind = type(ev)
        if name in self.pipelines:
            if kind is Tick and not self._tick_matters(name, ev.t_ns):
                return []
            self._record(ev)
            self._take(name, ev)
        elif kind is Chunk or name:
            raise CaptureError(f"bytes of a link {name!r} the capture does not list "
                               f"(links: {', '.join(self.pipelines)})")
        else:  # a Tick or Gap of no link (a file reader's gap over damage): every link's
            if kind is Tick and not any(self._tick_matters(n, ev.t_ns) for n in self._names):
                return []
            self._record(ev)
            for n in self._names:
                self._take(n, ev)
        return self._release()

    def _record(self, ev) -> None:
        for s in self.sinks:
            s.raw(ev)

    def _tick_matters(self, name: str, t_ns: int) -> bool:
        """Would a tick at t_ns close bytes, or time out a request once the link's queued frames are paired?"""
        p = self.pipelines[name]
        if p.tick_matters(t_ns):
            return True
        timeout_for = p.pairer.timeout_for
        return any(type(f) is Frame and f.unit is not None and t_ns - f.t_end_ns > timeout_for(f.unit)
                   for f in self._queues[name])

    def _take(self, name: str, ev) -> None:
        """A recorded event of link `name`: its framed frames into the link's queue, the clock on."""
        p = self.pipelines[name]
        kind = type(ev)
        if kind is Chunk:
            self._reach[name] = 0 if ev.byte_t_ns is not None else self._slack[name]
        t = ev.t_end_ns if kind is Gap else ev.t_ns
        if self._clock is None or t > self._clock:
            self._clock = t
        self._stalled.discard(name)
        q = self._queues[name]
        q.extend(p.framed(ev))
        if kind is Tick:  # the pairer's timeout, after the frames framed before it
            if q:
                q.append(t)
            else:
                self._ready_add(p.timed_out(t))
        elif kind is Gap and ev.state:  # the next file's decoder state, after the frames before the gap
            if q:
                q.append(ev.state)
            else:
                p.carry_in(ev.state)

    # ------------------------------------------------------------ the merge
    def _ready_add(self, frames: list[Frame]) -> None:
        for f in frames:
            heapq.heappush(self._ready, (f.index, f))

    def _horizon(self, name: str) -> int:
        """No frame link `name` has yet to hand on starts before this (module doc)."""
        h = self._clock - self._reach[name]
        q = self._queues[name]
        if q and q[0].t_ns < h:
            h = q[0].t_ns
        since = self.pipelines[name].framer.pending_since()
        return h if since is None or since >= h else since

    def _blocking(self, best: str, t_ns: int, horizons: dict[str, int]) -> list[str]:
        """The links (not stalled) that may still hand on a frame before link `best`'s frame at t_ns (ties: the
        earlier link first); `horizons` caches _horizon."""
        order, out = self._order, []
        for n in self._names:
            if n == best or n in self._stalled:
                continue
            h = horizons.get(n)
            if h is None:
                h = horizons[n] = self._horizon(n)
            if h < t_ns or (h == t_ns and order[n] < order[best]):
                out.append(n)
        return out

    def decoder_state(self) -> dict:
        """Every link's carried decoder state (Pipeline.decoder_state)."""
        return {name: reg.carried() for name, reg in self.registries.items()}

    def state_version(self) -> int:
        return sum(reg.version() for reg in self.registries.values())

    def waiting(self) -> dict:
        """Every link's request waiting for its answer (Pipeline.waiting)."""
        out = {}
        for name, p in self.pipelines.items():
            queued = [x for x in self._queues[name] if type(x) is Frame]
            if not queued:
                out.update(p.waiting())
                continue
            # the merge holds frames its pairer has not seen yet (their bytes are before the cut): what waits is
            # what a copy of the pairer waits for once it has them (copies: the real ones are paired later)
            pairer, frames = copy.deepcopy((p.pairer, queued))
            for f in frames:
                pairer.push(f)
            w = pairer.waiting()
            if w is not None:
                out[name] = w
        return out

    def _release(self, final: bool = False) -> list[Frame]:
        """Stage 1 (queues, in time order, numbered, paired) then stage 2 (in number order) to the sinks."""
        queues, pipelines = self._queues, self.pipelines
        if not final and not self._ready and not any(queues.values()):
            return []  # most reads close no frame
        clock, hold, names, stalled = self._clock, self.hold_ns, self._names, self._stalled
        horizons: dict[str, int] = {}  # a link's changes only when its own queue does
        while True:
            best, best_t = None, 0
            for name in names:
                q = queues[name]
                while q and type(q[0]) is not Frame:  # a tick or a gap's state, once the frames before it are paired
                    item = q.popleft()
                    if type(item) is int:
                        self._ready_add(pipelines[name].timed_out(item))
                    else:
                        pipelines[name].carry_in(item)
                if q and (best is None or q[0].t_ns < best_t):
                    best, best_t = name, q[0].t_ns
            if best is None:
                break
            if not final:
                blocked = self._blocking(best, best_t, horizons)
                if blocked:
                    if clock - best_t <= hold:
                        break
                    stalled.update(blocked)  # held past the bound: go on without them (module doc)
            f = queues[best].popleft()
            horizons.pop(best, None)
            f.index = self._numbered
            self._numbered += 1
            self._ready_add(pipelines[best].paired([f]))
        if final:
            for p in pipelines.values():
                self._ready_add(p.flush_pairer())
        ready, out = self._ready, []
        while ready:
            index, f = ready[0]
            if index > self._next_out and not final and clock - f.t_ns <= hold:
                break  # a lower number is still held in its link's pairer
            heapq.heappop(ready)
            if index >= self._next_out:
                self._next_out = index + 1
            out.append(f)
        if out:
            for s in self.sinks:
                frame = s.frame
                for f in out:
                    frame(f)
            self.frames_out += len(out)
        return out

    # ------------------------------------------------------------ state, end
    def settled(self, link: str | None = None) -> int:
        """As Pipeline.settled, of `link` or of the least settled link (2: nothing pending on any link); frames
        still waiting in the merge count as pending (1)."""
        if link in self.pipelines:
            return self._settled(link)
        least = min(self._settled(n) for n in self._names)
        return 1 if least == 2 and self._ready else least

    def _settled(self, name: str) -> int:
        s = self.pipelines[name].settled()
        return 1 if s == 2 and self._queues[name] else s

    def numbered(self) -> int:
        """How many frames have been numbered so far (the next frame's number)."""
        return self._numbered

    def cut_state(self, offset: int | None = None) -> tuple:
        """As Pipeline.cut_state, of every link and of the merge (its queues, the links it went on without,
        how far back each link's reads reach, the clock)."""
        offset = self._numbered if offset is None else offset

        def item(x):
            return (x.index - offset, x.t_ns, x.raw) if type(x) is Frame else repr(x)

        return (tuple((n, p.cut_state(offset), tuple(item(x) for x in self._queues[n]))
                      for n, p in self.pipelines.items()),
                tuple(sorted(self._reach.items())), tuple(sorted(self._stalled)),
                tuple(i - offset for i, _ in sorted(self._ready, key=lambda r: r[0])),
                self._next_out - offset, self._clock)

    def flush(self) -> list[Frame]:
        """End of input: every link's pending bytes and held requests settled, every frame handed on in order."""
        for name, p in self.pipelines.items():
            self._queues[name].extend(p.framed_flush())
        return self._release(final=True)

    def close(self) -> None:
        close_sinks(self.sinks)

    def finish(self) -> list[Frame]:
        try:
            return self.flush()
        finally:
            self.close()
