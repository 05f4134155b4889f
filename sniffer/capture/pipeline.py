"""One pipeline for live capture, replay and tests.

    events (Chunk/Tick/Gap) -> framer -> pairer -> registry.decode -> sinks

`Pipeline.feed(event)` and `Pipeline.flush()` return the settled, decoded
frames (and hand them to the sinks); `close()` closes the sinks.  A sink is
any object with `start(info)`, `raw(event)`, `frame(frame)` and `close()`
(sniffer.sinks.base.Sink).  Sans-I/O: sniffer.capture.session drives it.

Several links (sniffer.capture.links.LinkPipelines) run one Pipeline per link, without
sinks, and drive its two stages themselves: `framed(ev)` (the frames an event
closes, not yet paired) and `paired(frames)` / `timed_out(t)` (pairing and
decoding), so the frames of every link can be put in time order and numbered
in between.  `link` names the line (set on every frame); `directions` maps a
wire (Chunk.channel) to the one role its frames can have (--tap: the master's
pair carries requests, the slaves' pair responses; a logic capture's channels:
CaptureInfo.extra["channel_roles"], see `roles_of`).  Chunks of a logic capture's
driver-enable windows (Chunk.de) put the driver's turn-on and turn-off times on
their frames (sniffer.sources.driver_enable).

What the decoders know that scales or names values (decoders/carry.py) is
`decoder_state()`; `state_version()` changes when it may have.  A Gap that
carries a `state` (the next segment's, after a hole in a replayed folder)
starts the decoders from it once the frames before the gap are out
(`carry_in`).
"""

from __future__ import annotations

from collections.abc import Iterable

from sniffer import codes, protocols
from sniffer.codes import note
from sniffer.events import WAITING_KEY, CaptureInfo, Chunk, Gap, Tick
from sniffer.frame import CAN_REQ, CAN_RSP, Frame
from sniffer.line import LineSettings
from sniffer.capture.pairer import DEFAULT_TIMEOUT_MS, Pairer


_ROLE_BITS = {"request": CAN_REQ, "response": CAN_RSP}


def roles_of(info: CaptureInfo) -> dict[str, int] | None:
    """The wire -> role map a capture records (a logic capture's --rx/--tx/--de channels), as `directions`."""
    roles = info.extra.get("channel_roles") if isinstance(info.extra, dict) else None
    if not isinstance(roles, dict):
        return None
    return {str(ch): _ROLE_BITS[r] for ch, r in roles.items() if r in _ROLE_BITS} or None


class Pipeline:
    def __init__(
        self,
        info: CaptureInfo,
        line: LineSettings,
        registry,
        sinks: Iterable = (),
        protocol: str = "modbus-rtu",
        timeout_ms: float = DEFAULT_TIMEOUT_MS,
        unit_timeouts: dict[int, float] | None = None,
        *,
        link: str = "",
        directions: dict[str, int] | None = None,
        start: bool = True,
    ) -> None:
        self.info = info
        self.line = line
        self.registry = registry
        self.sinks = list(sinks)
        self.framer = protocols.get(protocol).framer(line)
        if info.time_source in ("none", "net"):  # no real time / every read's time after a network: said per frame
            self.framer.time_source = info.time_source
        self.pairer = Pairer(timeout_ms, unit_timeouts)
        self.frames_out = 0
        self.bytes_in = 0
        self.noise_bytes = 0
        self._gap_pending: Gap | None = None
        self.link = link
        self.directions = directions or None
        waiting = info.extra.get(WAITING_KEY) if info is not None and isinstance(info.extra, dict) else None
        if isinstance(waiting, dict) and isinstance(waiting.get(link), dict):
            self.pairer.resume(waiting[link])  # a segment cut while a request waited: its answer is this one's
        self.driver_enable = None  # sniffer.sources.driver_enable.DriverEnable, made by the first DE chunk
        if start:
            for s in self.sinks:
                s.start(info)

    def feed(self, ev) -> list[Frame]:
        """The frames `ev` settles (and the event to the sinks' raw)."""
        if type(ev) is Tick and not self.tick_matters(ev.t_ns):
            return []  # a tick that changes nothing is not recorded
        for s in self.sinks:
            s.raw(ev)
        out = self.paired(self.framed(ev))
        if type(ev) is Tick:
            out += self.timed_out(ev.t_ns)
        elif type(ev) is Gap and ev.state:
            self.carry_in(ev.state)
        return out

    def tick_matters(self, t_ns: int) -> bool:
        """Would a Tick at t_ns close pending bytes or time out the pending request?"""
        return self.framer.would_close(t_ns) or self.pairer.would_time_out(t_ns)

    def framed(self, ev) -> list[Frame]:
        """The first stage: the frames `ev` closes, in line order, marked but not yet paired (nothing recorded)."""
        if type(ev) is Chunk:
            self.bytes_in += len(ev.data)
            if ev.de is not None:
                self._note_de(ev)
            frames = self.framer.feed(ev)
        elif type(ev) is Tick:
            frames = self.framer.tick(ev.t_ns)
        elif type(ev) is Gap:
            self._gap_pending = ev
            frames = self.framer.flush()
        else:
            raise TypeError(f"unknown event {ev!r}")
        if frames:
            self._mark(frames)
            if self.driver_enable is not None:
                self.driver_enable.mark(frames)
        return frames

    def close_before(self, ev) -> list[Frame]:
        """The frames feed(ev) would hand on first, before any of ev's own bytes, if the silence before ev
        (a Chunk) closes every byte the framer holds; handed on now ([] if it does not).  feed(ev) then gives
        the rest: the same frames in the same order as feed(ev) alone, but before ev reaches the sinks' raw
        (sniffer.parallel cuts a capture there, where nothing else is pending)."""
        if type(ev) is not Chunk or not self.framer.pending_bytes() or not self.framer.closes_before(ev):
            return []
        frames = self.framer.close_now()
        if frames:
            self._mark(frames)
            if self.driver_enable is not None:
                self.driver_enable.mark(frames)
        return self.paired(frames)

    def carry_in(self, state: dict) -> None:
        """A Gap's `state` (the decoder state recorded where the next file starts), once the frames before the
        gap are paired and decoded."""
        self.registry.carry_in(state.get(self.link) or {})

    def paired(self, frames: list[Frame]) -> list[Frame]:
        """The second stage: `frames` (from `framed`, in order) paired and decoded; the frames it settles."""
        if not frames:
            return frames
        out: list[Frame] = []
        push = self.pairer.push
        for f in frames:
            out.extend(push(f))
        return self._decode(out)

    def timed_out(self, t_ns: int) -> list[Frame]:
        """The frames a timeout tick at t_ns settles (after `paired` had the frames framed before it)."""
        return self._decode(self.pairer.tick(t_ns))

    def decoder_state(self) -> dict:
        """{link: the registry's carried state} (decoders/carry.py): what a part cut now starts with."""
        return {self.link: self.registry.carried()}

    def state_version(self) -> int:
        return self.registry.version()

    def waiting(self) -> dict:
        """{link: the request waiting for its answer} (Pairer.waiting), if one waits: what a segment cut now
        starts with (its metadata's WAITING_KEY), so read alone it pairs that answer as the whole capture does."""
        w = self.pairer.waiting()
        return {self.link: w} if w is not None else {}

    def settled(self) -> int:
        """Between events: 2 nothing is pending, 1 a request waits for its answer, 0 bytes wait in the framer.

        A capture cut at 2 (a rotated segment) replays alone to the frames it had in the whole."""
        if self.framer.pending_bytes():
            return 0
        return 1 if self.pairer.pending is not None or self.pairer.held else 2

    def numbered(self) -> int:
        """How many frames have been numbered so far (the next frame's number)."""
        return self.framer.index

    def cut_state(self, offset: int | None = None) -> tuple:
        """What crosses a cut between two events (sniffer.parallel: a capture decoded in parts), frame numbers
        counted from `offset` (default: the next one): two pipelines with equal cut states (and decoders that
        know the same) give the same frames from there on.  The decoders' part is theirs (DecoderRegistry)."""
        offset = self.numbered() if offset is None else offset
        gap = self._gap_pending
        de = self.driver_enable
        return (self.framer.cut_state(), self.pairer.cut_state(offset),
                None if gap is None else (gap.t_ns, gap.t_end_ns, gap.reason, gap.link, repr(gap.state)),
                None if de is None else repr(sorted(vars(de).items())), self.link, self.directions)

    def flush(self) -> list[Frame]:
        """End of input: every pending byte becomes a frame, every held request is settled."""
        out = self.paired(self.framed_flush())
        out += self.flush_pairer()
        return out

    def flush_pairer(self) -> list[Frame]:
        """End of input, the second stage (after `paired` had every frame): every held request settled."""
        return self._decode(self.pairer.flush())

    def framed_flush(self) -> list[Frame]:
        """End of input, the first stage: every pending byte becomes a frame (not yet paired)."""
        frames = self.framer.flush()
        if frames:
            self._mark(frames)
            if self.driver_enable is not None:
                self.driver_enable.mark(frames)
        return frames

    def close(self) -> None:
        """Close every sink, even if one fails (the first failure is raised)."""
        close_sinks(self.sinks)

    def finish(self) -> list[Frame]:
        """flush() then close()."""
        try:
            return self.flush()
        finally:
            self.close()

    def _note_de(self, c: Chunk) -> None:
        if self.driver_enable is None:
            from sniffer.sources.driver_enable import DriverEnable

            self.driver_enable = DriverEnable(self.line.char_ns)
        self.driver_enable.note(c)

    def _mark(self, frames: list[Frame]) -> None:
        """What the line says about a frame before pairing: a gap before it, its link, a tapped wire's role."""
        gap = self._gap_pending
        if gap is not None:
            for f in frames:
                if f.t_ns >= gap.t_end_ns:
                    f.annotations.append(
                        note(codes.SOURCE_GAP,
                             f"{gap.reason}; {(gap.t_end_ns - gap.t_ns) / 1e9:.1f} s without data before this frame",
                             0, len(f.raw))
                    )
                    self._gap_pending = None
                    break
        link, directions = self.link, self.directions
        if link or directions is not None:
            for f in frames:
                f.link = link
                if directions is not None:
                    can = directions.get(f.channel, 0)
                    if f.role_fits & can:
                        f.role_fits = can

    def _decode(self, frames: list[Frame]) -> list[Frame]:
        decode = self.registry.decode
        sinks = self.sinks
        for f in frames:
            decode(f)
            # a request is decoded before its response, which holds its own link to it:
            # once decoded, a frame's link can go, so transactions are collected
            f.peer = None
            if f.protocol == "noise":
                self.noise_bytes += len(f.raw)
            for s in sinks:
                s.frame(f)
        self.frames_out += len(frames)
        return frames


def close_sinks(sinks) -> None:
    """Close every sink, even if one fails (the first failure is raised)."""
    first_error = None
    for s in sinks:
        try:
            s.close()
        except Exception as e:  # noqa: BLE001 - re-raised below
            first_error = first_error or e
    if first_error is not None:
        raise first_error
