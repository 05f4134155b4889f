"""What the diagnosis engine knows per link and unit, and the base of a group of findings (one module each)."""

from __future__ import annotations

from collections import OrderedDict
from typing import TYPE_CHECKING

from sniffer.frame import Frame
from sniffer.diagnose.episodes import Windows
from sniffer.diagnose.finding import Finding
from sniffer.diagnose.stats import Quantiles, TimeBins

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis


class Unit:
    """What the engine knows about one unit of one link."""

    __slots__ = ("unit", "requests", "answers", "good", "exceptions", "no_response", "retries", "late", "lat",
                 "lat_bins", "first_ns", "last_ns", "frames", "damaged_answers", "answered_retries", "echoes",
                 "plain_requests", "plain_answers", "garbled", "first_answer", "last_answer", "_typical")

    def __init__(self, unit: int) -> None:
        self.unit = unit
        self.requests = 0  # CRC-good requests to it
        self.answers = 0  # answers paired to its requests (damaged ones too)
        self.good = 0  # CRC-good frames naming it: it is on the line
        self.exceptions = 0
        self.no_response = 0
        self.retries = 0
        self.late = 0  # answers that came after the master moved on (pair.late_response)
        self.lat = Quantiles()  # latency of its ordinary answers, ms
        self.lat_bins = TimeBins()
        self.first_ns: int | None = None
        self.last_ns = 0
        self.frames: list[int] = []  # a few frame numbers of its requests
        self.damaged_answers = 0
        self.answered_retries = 0
        # an echo (05/06/08: the answer repeats the request) cannot be told from the master's retry of it by
        # its bytes: these count apart, and a unit is judged on its other requests and answers
        self.echoes = 0  # answers that are byte for byte their request
        self.plain_requests = 0  # requests of other functions
        self.plain_answers = 0  # CRC-good answers to those
        self.garbled = 0  # damaged bursts (noise, CRC-bad frames of no request) where its answer was due
        self.first_answer: int | None = None  # frame numbers of its first and last ordinary answer
        self.last_answer: int | None = None
        self._typical: tuple[int, float] | None = None

    @property
    def answered(self) -> bool:
        """It answered something the master's own retry cannot have been (or it is only ever written)."""
        return self.plain_answers > 0 or (self.plain_requests == 0 and self.answers > 0)

    @property
    def present(self) -> bool:
        return self.good > 0

    def typical(self) -> float:
        """The median of its ordinary answer times, worked out again only as their number doubles."""
        n = self.lat.n
        if self._typical is None or n >= 2 * self._typical[0]:
            self._typical = (n, self.lat.median() or 0.0)
        return self._typical[1]


class Link:
    """One line (one link of several): its settings and figures."""

    __slots__ = ("name", "resolved", "registry", "line", "char_ns", "t35_ns", "units", "first_ns", "last_ns", "frames",
                 "bytes", "good_frames", "good_bytes", "matched_bytes", "crc_bad", "noise_frames", "noise_bytes",
                 "last_role", "last_unit", "due", "slot", "cut", "time_sources", "requests", "echo_retries", "damage",
                 "gaps_ns")

    def __init__(self, name: str, resolved=None, registry=None) -> None:
        self.name = name
        self.resolved = resolved
        self.registry = registry
        line = resolved.line if resolved is not None else None
        self.line = line
        self.char_ns = line.char_ns if line is not None else 0
        self.t35_ns = line.t35_ns if line is not None else 0
        self.units: dict[int, Unit] = {}
        self.first_ns: int | None = None
        self.last_ns = 0
        self.frames = 0
        self.bytes = 0
        self.good_frames = 0
        self.good_bytes = 0
        self.matched_bytes = 0  # in frames whose CRC matches, flagged bytes or not (modbus.crc.unproven)
        self.crc_bad = 0
        self.noise_frames = 0
        self.noise_bytes = 0
        self.last_role = ""  # the role of the last frame that was not noise
        self.last_unit: Unit | None = None  # ... and the unit it named or answered for
        # (unit, t_end_ns, answer length or None) of a request whose answer has not come yet
        self.due: tuple[int, int, int | None] | None = None
        self.slot: Unit | None = None  # this frame is a damaged burst in that unit's answer slot (Diagnosis.frame)
        # this frame is an answer whose damage is a driver's (unit, "first" | "last"): its first or last byte (set
        # by wiring.py for the groups after it: a cut's damage says nothing of the load's interference)
        self.cut: tuple[int, str] | None = None
        self.time_sources: dict[str, int] = {}
        self.requests: OrderedDict[int, tuple] = OrderedDict()  # index -> (unit, request, its request_type)
        self.echo_retries: OrderedDict[int, None] = OrderedDict()  # "answers" that are the master's retry
        # the silence the line needs around its frames: before a request or other frame the gap seen up to t3.5,
        # before an answer the whole turnaround (the line is the unit's until it answers)
        self.gaps_ns = 0
        self.damage = Windows()  # frames per window of time, and those damaged (noise, CRC errors, UART flags)

    @property
    def busy_ns(self) -> int:
        """Characters on the wire."""
        return self.bytes * self.char_ns

    def unit(self, u: int) -> Unit:
        x = self.units.get(u)
        if x is None:
            x = self.units[u] = Unit(u)
        return x

    def decoder(self, model: str | None):
        """The decoder of a model on this link (None: none).  A unit's model is the one its frame names
        (Frame.model): the registry's naming now can be ahead of or behind the frame in hand when the capture
        was decoded by parts."""
        return None if self.registry is None or model is None else self.registry.decoders.get(model)

    def request_of(self, f: Frame):
        """The request a response is paired to (unit, frame, type), if it is still remembered."""
        return None if f.pair is None else self.requests.get(f.pair)


class Group:
    """A group of findings (one module): takes frames, gives findings.  Override what you use: the engine
    calls only the handlers a group has."""

    def request(self, f: Frame, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        """A CRC-good request naming a unit; `key` its request_type."""

    def response(self, f: Frame, link: Link, unit: Unit | None, codes: frozenset, req: tuple | None) -> None:
        """A response; `unit` the one it answers (None: nobody known), `req` (unit, request, type) or None."""

    def other(self, f: Frame, link: Link, unit: Unit | None, codes: frozenset) -> None:
        """Any other frame but noise (a damaged request, a frame of no role)."""

    def noise(self, f: Frame, link: Link, codes: frozenset) -> None:
        pass

    def findings(self, d: Diagnosis) -> list[Finding]:
        return []
