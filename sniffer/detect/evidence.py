"""What one listen says about its setting: frames that fit each protocol, UART errors, timing.

`Reading` runs one protocol's framer and a pairer over a listen's bytes;
`Evidence` sums a listen up and judges it:

* `fits`: a request/response pair and 2+ frames whose CRC/LRC is good and whose
  shape fits the protocol, 80 % of the bytes in such frames, UART errors under 1 %
  of the bytes, and characters no faster than the format allows;
* `certain`: it fits and `doubts` finds nothing: no UART error at all, 4+ frames
  and 2+ pairs, bytes of both parities (so a wrong parity setting would have shown
  as errors), one protocol clearly ahead of the others, and the characters'
  spacing says how many stop bits (a UART receives 8E1 and 8E2, 8N1 and 8N2 alike:
  it checks the first stop bit only);
* `line`: the settings the evidence supports: the listen's, or its twin with the
  other number of stop bits when the spacing says so and the twin is never
  listened at itself (an 8E1 listen whose characters come 12 bits apart: 8E2);
* timing: within a frame the sender sends back to back, so the reads inside a
  fitting frame tell how long a character takes: `bits_per_char` = that time x
  baud.  Fewer bits than the format has is impossible; more is a sender that
  pauses between characters.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from dataclasses import dataclass, field
from statistics import median

from sniffer import codes
from sniffer.framing import pd as pd_framing
from sniffer.events import Chunk
from sniffer.frame import REQUEST, RESPONSE
from sniffer.line import LineSettings
from sniffer.capture.pairer import Pairer
from sniffer.detect.candidates import LISTENED, TWINS, fmt_of, setting
from sniffer.detect.units import UnitPolls, UnitSeen

# a good CRC/LRC on a frame whose shape these codes question is no evidence for the protocol
MISFIT = frozenset(c.code for c in (
    codes.LENGTH_MISMATCH, codes.STRUCTURE_MISMATCH, codes.FUNCTION_UNKNOWN, pd_framing.LEN_MISMATCH,
    pd_framing.FUNCTION_UNKNOWN, codes.PAIR_MISMATCH, codes.ASCII_NO_CRLF, pd_framing.NO_CRLF,
))
# a silence between reads is sure beyond t3.5 plus this (covers a USB adapter's 16 ms latency timer; the
# framers' 50 ms for live capture also covers a host that wakes late, and would hold decisions back here)
READ_SLACK_NS = 20_000_000
MIN_SPAN_NS = 3_000_000  # a frame's reads must span this long to time it (a read can come 0.1-0.3 ms late)
MIN_TIMED_FRAMES, MIN_TIMED_NS = 6, 40_000_000  # and this many frames timed, this long in all
LEAST_SQUEEZED = 0.1  # the share of timed frames taken as squeezed least by late reads (not one outlier)
TIMING_TOLERANCE = 0.07  # measured bits per character within 7 % of the format's: it fits exactly
TWIN_MARGIN = 0.2  # ... and for 8N1 / 8N2, nearer its own by this many bits than the other's
FIT_COVERAGE, FIT_ERRORS = 0.8, 0.01
CERTAIN_MARGIN = 0.25  # the best protocol's share of bytes in pairs ahead of the next one's
CERTAIN_CHARS = 48  # the best protocol's coverage ahead of the next one's


KEEP_ANSWERS = 20_000  # answers kept a listen for naming the units' models (a few MB at most)


class Reading:
    """One protocol's framer and a pairer over a listen's bytes (optionally masked to 7 bits)."""

    def __init__(self, protocol, rx: LineSettings, mask: int | None = None) -> None:
        self.name = protocol.name
        self.framer = protocol.framer_class(rx, read_slack_ns=READ_SLACK_NS)
        self.pairer = Pairer()
        self.mask = mask
        self.pos = 0  # characters the framer has decided on
        self.settled = 0  # characters in the frames the pairer has settled
        self.frames = self.fit_frames = self.fit_bytes = self.pairs = self.paired_bytes = 0
        self._fit_requests: dict[int, int] = {}  # index -> length of the last fitting requests
        self.spans: list[tuple[int, int]] = []  # character spans of the fitting frames
        self.units = UnitPolls()
        self.answers: list = []  # fitting answers paired with their fitting requests: what names the models
        self._span: dict[int, tuple[int, int]] = {}  # frame index -> span, until the pairer settles it

    def feed(self, chunk: Chunk) -> None:
        if self.mask is not None:
            chunk = Chunk(chunk.t_ns, bytes(b & self.mask for b in chunk.data))
        self._framed(self.framer.feed(chunk))

    def tick(self, t_ns: int) -> None:
        if self.framer.would_close(t_ns):
            self._framed(self.framer.tick(t_ns))
        if self.pairer.would_time_out(t_ns):
            self._settled(self.pairer.tick(t_ns))

    def _framed(self, frames) -> None:
        for f in frames:
            self._span[f.index] = (self.pos, self.pos + len(f.raw))
            self.pos += len(f.raw)
            self._settled(self.pairer.push(f))

    def _settled(self, frames) -> None:
        for f in frames:
            span = self._span.pop(f.index)
            self.frames += 1
            self.settled += len(f.raw)
            if not f.crc_ok or any(a.code in MISFIT for a in f.annotations):
                continue
            self.fit_frames += 1
            self.fit_bytes += len(f.raw)
            self.spans.append(span)
            if f.role == RESPONSE and f.pair in self._fit_requests:
                self.pairs += 1
                if len(self.answers) < KEEP_ANSWERS:
                    self.answers.append(f)
                self.paired_bytes += len(f.raw) + self._fit_requests.pop(f.pair)
            elif f.role == REQUEST and f.unit is not None:
                if len(self._fit_requests) > 8:
                    self._fit_requests.pop(next(iter(self._fit_requests)))
                self._fit_requests[f.index] = len(f.raw)
                self.units.add(f)

    @property
    def coverage(self) -> float:
        """The share of the bytes in frames that fit."""
        return self.fit_bytes / self.settled if self.settled else 0.0

    @property
    def paired(self) -> float:
        """The share of the bytes in fitting requests with their fitting responses."""
        return self.paired_bytes / self.settled if self.settled else 0.0


@dataclass(frozen=True)
class Score:
    protocol: str
    frames: int
    fit_frames: int
    pairs: int
    coverage: float
    paired: float


@dataclass
class Evidence:
    rx: LineSettings
    seconds: float
    chars: int
    skipped: int
    errors: int
    nul_errors: int
    scores: list[Score]  # best first
    bits_per_char: float | None  # measured inside fitting frames (None: not enough)
    timed_s: float  # how long the timed spans inside frames add up to
    both_parities: bool  # bytes of even and of odd popcount seen (a wrong parity would have shown)
    units: list[UnitSeen] = field(default_factory=list)
    answers: list = field(default_factory=list, repr=False)  # the best protocol's paired answers (Reading.answers)
    bursts: int = 0  # runs of reads between silences
    pending: int = 0  # bytes the framers have not decided on yet (the most of any protocol)
    hint: str | None = None  # the format the bytes point to (for the search's order)
    found: bool = False  # some protocol frames these bytes (maybe at another format): the baud is right
    bits_least_squeezed: float | None = None  # bits per character of the frames a late read squeezed least

    @property
    def fmt(self) -> str:
        return fmt_of(self.rx)

    @property
    def best(self) -> Score | None:
        return self.scores[0] if self.scores and self.scores[0].fit_frames else None

    @property
    def line(self) -> LineSettings:
        """The settings this listen's evidence supports (see the module doc)."""
        told = self.stop_bits_told()
        if told is not None and told != self.fmt and told not in LISTENED:
            return setting(self.rx.baud, told)
        return self.rx

    @property
    def timing(self) -> str:
        """"exact", "slower" (pauses between characters), "impossible" (faster than the format) or "?", for
        the settings the evidence supports (`line`)."""
        if self.bits_per_char is None:
            return "?"
        bits = self.line.bits_per_char
        if self.bits_per_char < bits * (1 - TIMING_TOLERANCE):
            # a read the host takes late squeezes its frame's measured time, never stretches it: faster than
            # the format only if even the frames squeezed least are (a busy host squeezes most of them)
            least = self.bits_least_squeezed
            return "impossible" if least is None or least < bits * (1 - TIMING_TOLERANCE) else "?"
        return "exact" if self.bits_per_char <= bits * (1 + TIMING_TOLERANCE) else "slower"

    def stop_bits_told(self) -> str | None:
        """Of this listen's format and its twin (the other number of stop bits), the one whose character
        time the measured spacing fits exactly and nearer than the other's; None: the spacing does not tell
        (not measured, or a sender pausing between characters)."""
        twin = TWINS.get(self.fmt)
        bits = self.bits_per_char
        if twin is None or bits is None:
            return None
        own_bits, twin_bits = self.rx.bits_per_char, setting(self.rx.baud, twin).bits_per_char
        for fmt, want, other in ((self.fmt, own_bits, twin_bits), (twin, twin_bits, own_bits)):
            if abs(bits - want) <= want * TIMING_TOLERANCE and abs(bits - want) + TWIN_MARGIN < abs(bits - other):
                return fmt
        return None

    def timing_tells_twins(self) -> bool:
        """Does the characters' spacing say this listen's format rather than its twin?"""
        return self.stop_bits_told() == self.fmt

    @property
    def fits(self) -> bool:
        b = self.best
        return (b is not None and b.pairs >= 1 and b.fit_frames >= 2 and b.coverage >= FIT_COVERAGE
                and self.errors <= max(1, self.chars * FIT_ERRORS) and self.timing != "impossible")

    @property
    def certain(self) -> bool:
        return self.fits and not self.doubts()

    def doubts(self) -> list[str]:
        """Why a listen that fits is not certain (empty: it is)."""
        out = []
        b = self.best
        if self.errors:
            out.append(f"{self.errors} UART error{'s' if self.errors > 1 else ''}")
        if self.chars < CERTAIN_CHARS or b is None or b.pairs < 2 or b.fit_frames < 4:
            out.append("heard too little" + (f" ({b.fit_frames} frames, {b.pairs} pairs)" if b else ""))
        if not self.both_parities:
            out.append("too few bytes of each parity to rule out the other parity settings")
        if b is not None and len(self.scores) > 1 and self.scores[1].paired > b.paired - CERTAIN_MARGIN:
            out.append(f"{self.scores[1].protocol} fits nearly as well as {b.protocol}")
        stop = self.stop_bits_doubt()
        if stop:
            out.append(stop)
        return out

    def stop_bits_doubt(self) -> str | None:
        """Why the stop bits are not known, if they are not: the twins receive alike and the timing does
        not tell them apart (or tells the twin, which is listened at itself)."""
        told = self.stop_bits_told()
        if self.fmt not in TWINS or told == fmt_of(self.line):
            return None
        bits = self.bits_per_char
        spacing = "not measurable" if bits is None else f"characters {bits:.1f} bits apart"
        if told is None:
            return f"{self.fmt} and {TWINS[self.fmt]} receive alike and the timing does not tell them apart ({spacing})"
        return f"the timing says {told}, not {self.fmt} ({spacing})"

    @property
    def only_stop_bits_open(self) -> bool:
        """It fits, and would be certain but for the stop bits its evidence cannot tell."""
        return self.fits and self.doubts() == [self.stop_bits_doubt()]

    @classmethod
    def of(cls, w, t_ns: int) -> Evidence:
        scores = sorted((Score(r.name, r.frames, r.fit_frames, r.pairs, r.coverage, r.paired)
                         for r in w.readings.values()),
                        key=lambda s: (s.paired, s.coverage, s.fit_frames), reverse=True)
        best = w.readings[scores[0].protocol]
        bits, timed, least = _timing(w.reads, best.spans, w.rx.baud)
        even = w.popcounts[0][0] + w.popcounts[1][0]
        odd = w.popcounts[0][1] + w.popcounts[1][1]
        ev = cls(w.rx, (t_ns - w.t0_ns) / 1e9, w.chars, w.skipped, w.errors, w.nul_errors, scores, bits, timed,
                 min(even, odd) >= 3, best.units.seen() if scores[0].fit_frames else [])
        ev.bursts = w.bursts
        ev.answers = best.answers if scores[0].fit_frames else []
        ev.bits_least_squeezed = least
        ev.pending = w.chars - min(r.pos for r in w.readings.values())
        hinted = [h for h in w.hints.values() if h.fit_frames >= 2 and h.coverage > 0.5]
        ev.found = scores[0].fit_frames >= 2 or bool(hinted)
        ev.hint = _hint(w, ev, bool(hinted))
        return ev


def _timing(reads: list[tuple[int, int]], spans: list[tuple[int, int]],
            baud: int) -> tuple[float | None, float, float | None]:
    """Bits per character from the reads that end inside a fitting frame, before its last character; the
    seconds timed; and the bits per character of the frames squeezed least (LEAST_SQUEEZED of them are higher).

    A read returns a little after its last character came: at most a character later when more
    characters follow (the adapter sends what it has), up to its latency timer after the frame's
    last one.  Reads ending before the last character are late alike, and their differences exact
    but for that lateness, which beats with the adapter's packet period (a frame's estimate can be
    10 % off either way): the time over the characters of all frames averages it out.  A frame whose
    read the host took late is left out (its estimate a third off the median).
    """
    ends = [n for _, n in reads]
    per_frame = []  # (bits per character, characters, time spanned)
    for a, b in spans:
        i = bisect_left(ends, a + 1)  # the first read ending inside the frame
        j = bisect_right(ends, b - 1) - 1  # the last one ending before its last character
        dt = reads[j][0] - reads[i][0] if j > i else 0
        if dt >= MIN_SPAN_NS:
            chars = ends[j] - ends[i]
            per_frame.append((dt / chars * baud / 1e9, chars, dt))
    if len(per_frame) < MIN_TIMED_FRAMES:
        return None, sum(dt for *_, dt in per_frame) / 1e9, None
    mid = median(bits for bits, *_ in per_frame)
    kept = [(chars, dt) for bits, chars, dt in per_frame if 0.75 * mid <= bits <= 1.33 * mid]
    timed = sum(dt for _, dt in kept)
    if len(kept) < MIN_TIMED_FRAMES or timed < MIN_TIMED_NS:
        return None, timed / 1e9, None
    ranked = sorted(bits for bits, *_ in per_frame)
    least = ranked[min(len(ranked) - 1, int(len(ranked) * (1 - LEAST_SQUEEZED)))]
    return timed / sum(chars for chars, _ in kept) * baud / 1e9, timed / 1e9, least


def _hint(w, ev: Evidence, seven_bit: bool) -> str | None:
    """The format the bytes of this listen point to, if any."""
    n = w.chars
    if not n:
        return None
    if seven_bit:  # ASCII framed with bit 7 stripped: bit 7 was a parity or stop bit
        for i, fmt in enumerate(("7N2", "7E1", "7O1")):
            if w.top_bits[i] >= 0.95 * n:
                return fmt
        return None
    (clean_even, clean_odd), (marked_even, marked_odd) = w.popcounts
    marked, clean = marked_even + marked_odd, clean_even + clean_odd
    if w.rx.parity == "N" and min(marked, clean) >= 4:
        # read without parity, a framing error where the parity bit was 0: with even parity the
        # bytes of even popcount, with odd parity the others (random bytes do not split so)
        if marked_even >= 0.95 * marked and clean_odd >= 0.95 * clean:
            return "8E1"
        if marked_odd >= 0.95 * marked and clean_even >= 0.95 * clean:
            return "8O1"
    if w.rx.parity == "N" and not marked and ev.bits_per_char is not None:
        return "8N2" if ev.bits_per_char > (w.rx.databits + 2.5) else "8N1"
    if ev.found and w.rx.parity != "N" and marked >= 0.95 * n:
        return "8O1" if w.rx.parity == "E" else "8E1"  # frames, but every byte a parity error: the other parity
    return None
