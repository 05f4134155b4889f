"""The Frame: one run of bytes from the line, with what we know about it.

Every input byte ends up in exactly one Frame; bytes that form no frame make a
noise frame (protocol "noise", with a reason).  The framer fills the wire
facts, the pairer the role / pair / latency, the decoder the meaning (and
which registers the frame wrote into its unit's shadow, `writes`).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol

from sniffer.codes import Annotation

REQUEST = "request"
RESPONSE = "response"
UNKNOWN = "unknown"
NOISE_ROLE = "noise"

_SEVERITY = {"info": 0, "warning": 1, "error": 2}

# candidate-role bits, set by the framer from structure
CAN_REQ = 1
CAN_RSP = 2


class LinkUnit(tuple):
    """A unit of one link of several: (link, unit), shown "link:unit", in order of link, then unit.

    A unit 1 on link A is not unit 1 on link B: viewers key their per-unit tables (units,
    registers, latencies) by `unit_key(frame)`, which is this for a frame of a multi-link capture
    and the plain unit number otherwise."""

    __slots__ = ()

    def __new__(cls, link: str, unit: int) -> LinkUnit:
        return tuple.__new__(cls, (link, unit))

    @property
    def link(self) -> str:
        return self[0]

    @property
    def unit(self) -> int:
        return self[1]

    def __str__(self) -> str:
        return f"{self[0]}:{self[1]}"

    def __repr__(self) -> str:
        return f"LinkUnit({self[0]!r}, {self[1]})"


def unit_key(f) -> int | LinkUnit | None:
    """The frame's unit as viewers key it: its number, or (link, number) in a capture of several links."""
    u = f.unit
    if u is None or not f.link:
        return u
    return LinkUnit(f.link, u)


class PointBlock(Protocol):
    """Points kept compactly by a decoder until someone reads them (decoders.generic.block)."""

    def points(self) -> list[dict]: ...

    def json(self) -> bytes: ...

    def samples(self) -> Iterable[tuple[str, int, int]]:
        """(name, address, value) of each point: unnamed registers' values are their raw numbers, with
        no unit or text (what sniffer.formats.mcap.foxglove reads, without building the dicts)."""
        ...


class Frame:
    __slots__ = (
        "index", "t_ns", "t_end_ns", "raw", "protocol", "unit", "function",
        "role_fits", "role", "crc_ok", "crc_expected", "time_source", "idle_before_ns",
        "annotations", "pair", "latency_ms", "model", "_points", "exception",
        "fields", "summary", "noise_reason", "channel", "peer", "adu", "encoded", "writes",
        "link", "de_on_ns", "de_off_ns",
    )

    def __init__(
        self,
        index: int,
        t_ns: int,
        t_end_ns: int,
        raw: bytes,
        protocol: str,
        unit: int | None = None,
        function: int | None = None,
        role_fits: int = 0,
        crc_ok: bool | None = None,
        crc_expected: int | None = None,
        time_source: str = "byte",
        idle_before_ns: int | None = None,
        noise_reason: str | None = None,
        channel: str = "",
    ) -> None:
        self.index = index
        self.t_ns = t_ns
        self.t_end_ns = t_end_ns
        self.raw = raw
        self.protocol = protocol
        self.unit = unit
        self.function = function
        self.role_fits = role_fits
        self.role = NOISE_ROLE if protocol == "noise" else UNKNOWN
        self.crc_ok = crc_ok
        self.crc_expected = crc_expected
        self.time_source = time_source
        self.idle_before_ns = idle_before_ns
        self.annotations: list[Annotation] = []
        self.pair: int | None = None
        self.latency_ms: float | None = None
        self.model: str | None = None
        # each with "span": [start, end) of its value's bytes in raw; see the `points` property
        self._points: list[dict] | PointBlock = []
        self.exception: dict | None = None
        self.fields: list | None = None  # decoded tree: [(name, value, start, end, children)]
        self.summary: str = ""
        self.noise_reason = noise_reason
        self.channel = channel
        self.peer: Frame | None = None  # the paired frame, until decoded (then dropped)
        # unit + PDU without CRC/LRC, in binary whatever the wire encoding (ASCII is hex text)
        self.adu: bytes = b""
        self.encoded: tuple[int, bytes] | None = None  # (t0_ns, JSON record): records.frame_json
        # what decoding this frame put into its unit's register shadow: [[table, start, [raw, ...]], ...]
        # (decoders.base.UnitState.commit writes both)
        self.writes: list[list] = []
        self.link = ""  # the link's name in a capture of several links (sniffer.capture.links), else ""
        # a logic capture's driver-enable line (sources/driver_enable.py): DE rise - first start bit, DE fall - end of
        # the last stop bit (ns); None: not known (no --de, not the first / last frame of its DE window)
        self.de_on_ns: int | None = None
        self.de_off_ns: int | None = None

    @property
    def points(self) -> list[dict]:
        """The decoded values, a list of dicts (name, address, raw, value, unit, span, ...).

        A decoder may set a PointBlock instead (a block of registers no model names, kept as its
        values): it becomes the list of dicts the first time anyone reads `points`, and the JSON
        record is written from the block without ever building them (sniffer.formats.records).
        """
        pts = self._points
        if type(pts) is not list:
            pts = self._points = pts.points()
        return pts

    @points.setter
    def points(self, value) -> None:
        self._points = value

    @property
    def is_noise(self) -> bool:
        return self.protocol == "noise"

    def worst_severity(self) -> str | None:
        worst = None
        for a in self.annotations:
            if worst is None or _SEVERITY[a.severity] > _SEVERITY[worst]:
                worst = a.severity
        return worst

    def __reduce__(self):
        """Pickled as its slots' values, without `peer` and the cached record (a frame decoded in a worker
        process crosses to the one that writes it: sniffer.parallel)."""
        return _rebuild, tuple([getattr(self, s) for s in _STATE])

    def __repr__(self) -> str:  # pragma: no cover - debugging aid
        return (
            f"Frame(#{self.index} t={self.t_ns} {self.protocol} {self.role} "
            f"unit={self.unit} fc={self.function} raw={self.raw.hex()} crc_ok={self.crc_ok})"
        )


_STATE = tuple(s for s in Frame.__slots__ if s not in ("peer", "encoded"))


def _rebuild(*values) -> Frame:
    f = Frame.__new__(Frame)
    for name, v in zip(_STATE, values):
        setattr(f, name, v)
    f.peer = None
    f.encoded = None
    return f
