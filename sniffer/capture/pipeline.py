"""One pipeline for live capture, replay and tests.

    events (Chunk/Tick/Gap) -> framer -> pairer -> registry.decode -> sinks

`Pipeline.feed(event)` and `Pipeline.flush()` return the settled, decoded
frames (and hand them to the sinks); `close()` closes the sinks.  A sink is
any object with `start(info)`, `raw(event)`, `frame(frame)` and `close()`
(sniffer.sinks.base.Sink).  Sans-I/O: sniffer.capture.session drives it.

Several links (sniffer.capture.links.LinkPipelines) run one Pipeline per link over the
same sinks: `link` names the line (set on every frame), `numbering` is the
capture-wide frame counter the links share (a frame is numbered as it leaves
its framer, before pairing, so pairs and notes name capture-wide numbers), and
`directions` maps a wire (Chunk.channel) to the one role its frames can have
(--tap: the master's pair carries requests, the slaves' pair responses; a
logic capture's channels: CaptureInfo.extra["channel_roles"], see `roles_of`).
Chunks of a logic capture's driver-enable windows (Chunk.de) put the driver's
turn-on and turn-off times on their frames (sniffer.sources.driver_enable).

What the decoders know that scales or names values (decoders/carry.py) is
`decoder_state()`; `state_version()` changes when it may have.  A Gap that
carries a `state` (the next segment's, after a hole in a replayed folder)
starts the decoders from it once the frames before the gap are out.
"""

from __future__ import annotations

from collections.abc import Iterable

from sniffer import codes, protocols
from sniffer.codes import note
from sniffer.events import CaptureInfo, Chunk, Gap, Tick
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
        numbering=None,
        directions: dict[str, int] | None = None,
        start: bool = True,
    ) -> None:
        self.info = info
        self.line = line
        self.registry = registry
        self.sinks = list(sinks)
        self.framer = protocols.get(protocol).framer(line)
        if info.time_source == "none":  # no real time in the input: no latency, no silence verdicts
            self.framer.time_source = "none"
        self.pairer = Pairer(timeout_ms, unit_timeouts)
        self.frames_out = 0
        self.bytes_in = 0
        self.noise_bytes = 0
        self._gap_pending: Gap | None = None
        self.link = link
        self.numbering = numbering
        self.directions = directions or None
        self.driver_enable = None  # sniffer.sources.driver_enable.DriverEnable, made by the first DE chunk
        if start:
            for s in self.sinks:
                s.start(info)

    def feed(self, ev, record: bool = True) -> list[Frame]:
        """The frames `ev` settles; `record=False`: the sinks have the event already (LinkPipelines)."""
        if type(ev) is Chunk:
            if record:
                for s in self.sinks:
                    s.raw(ev)
            self.bytes_in += len(ev.data)
            if ev.de is not None:
                self._note_de(ev)
            return self._settle(self.framer.feed(ev))
        if type(ev) is Tick:
            if not self.framer.would_close(ev.t_ns) and not self.pairer.would_time_out(ev.t_ns):
                return []  # a tick that changes nothing is not recorded
            if record:
                for s in self.sinks:
                    s.raw(ev)
            out = self._settle(self.framer.tick(ev.t_ns))
            out += self._decode(self.pairer.tick(ev.t_ns))
            return out
        if type(ev) is Gap:
            if record:
                for s in self.sinks:
                    s.raw(ev)
            self._gap_pending = ev
            out = self._settle(self.framer.flush())
            if ev.state:
                self.registry.carry_in(ev.state.get(self.link) or {})
            return out
        raise TypeError(f"unknown event {ev!r}")

    def decoder_state(self) -> dict:
        """{link: the registry's carried state} (decoders/carry.py): what a part cut now starts with."""
        return {self.link: self.registry.carried()}

    def state_version(self) -> int:
        return self.registry.version()

    def settled(self) -> int:
        """Between events: 2 nothing is pending, 1 a request waits for its answer, 0 bytes wait in the framer.

        A capture cut at 2 (a rotated segment) replays alone to the frames it had in the whole."""
        if self.framer.pending_bytes():
            return 0
        return 1 if self.pairer.pending is not None or self.pairer.held else 2

    def flush(self) -> list[Frame]:
        """End of input: every pending byte becomes a frame, every held request is settled."""
        out = self._settle(self.framer.flush())
        out += self._decode(self.pairer.flush())
        return out

    def close(self) -> None:
        """Close every sink, even if one fails (the first failure is raised)."""
        first_error = None
        for s in self.sinks:
            try:
                s.close()
            except Exception as e:  # noqa: BLE001 - re-raised below
                first_error = first_error or e
        if first_error is not None:
            raise first_error

    def finish(self) -> list[Frame]:
        """flush() then close()."""
        try:
            return self.flush()
        finally:
            self.close()

    def _settle(self, frames: list[Frame]) -> list[Frame]:
        if not frames:
            return frames
        if self.numbering is not None or self.directions is not None:
            self._mark(frames)
        if self.driver_enable is not None:
            self.driver_enable.mark(frames)
        out: list[Frame] = []
        push = self.pairer.push
        gap = self._gap_pending
        for f in frames:
            if gap is not None and f.t_ns >= gap.t_end_ns:
                f.annotations.append(
                    note(codes.SOURCE_GAP,
                         f"{gap.reason}; {(gap.t_end_ns - gap.t_ns) / 1e9:.1f} s without data before this frame",
                         0, len(f.raw))
                )
                self._gap_pending = gap = None
            out.extend(push(f))
        return self._decode(out)

    def _note_de(self, c: Chunk) -> None:
        if self.driver_enable is None:
            from sniffer.sources.driver_enable import DriverEnable

            self.driver_enable = DriverEnable(self.line.char_ns)
        self.driver_enable.note(c)

    def _mark(self, frames: list[Frame]) -> None:
        """A multi-link capture's number and link name; a tapped wire's role."""
        numbering, link, directions = self.numbering, self.link, self.directions
        for f in frames:
            if numbering is not None:
                f.index = next(numbering)
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

