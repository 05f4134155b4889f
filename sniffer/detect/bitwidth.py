"""A UART line's baud rate, parity, stop bits and polarity from its edges (sans-I/O): what a UART cannot tell.

A UART samples each bit once and checks the first stop bit only, so it takes
8E2 for 8E1 and 8N2 for 8N1 (and decodes 8N1 at 8E1 with parity errors it may
blame on noise).  A logic analyzer sees the waveform itself:

* bit width: every run between two edges lasts a whole number of bits; the
  shortest common run is one bit, and a least-squares fit of all short runs to
  their multiples gives the width to a fraction of a sample (`baud`); the rate
  is snapped to a standard one within 2 %;
* polarity: the line idles at mark; the level of the long runs is idle (low:
  `inverted`, the RS-232 side or an inverting probe);
* character format: each character is read at its bit centres (as a UART
  does, from its start edge); bit 9 (after 8 data bits) that always matches the
  data's even (odd) parity is a parity bit (no such bit 9, but a bit 8 that
  always matches bits 1-7: 7 data bits and parity, Modbus ASCII's 7E1); the
  shortest distance from one start
  edge to the next inside a burst (`pitch`) is start + data + parity + stop
  bits, so it tells 1 stop bit from 2 (a sender that always idles a bit between
  characters reads as 2: on the wire they are the same).

`measure(edges, rate)` takes one channel's edges [(sample, new level), ...] in
order (the first one may only say the level from there on: its run is not used) and gives a
`Measurement` (or None when the channel has too few edges).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field

STANDARD_BAUDS = (300, 600, 1200, 2400, 4800, 9600, 14400, 19200, 28800, 31250, 38400, 56000, 57600, 76800,
                  115200, 128000, 153600, 187500, 230400, 250000, 256000, 460800, 500000, 921600, 1000000,
                  1500000, 2000000, 3000000)
SNAP = 0.02
MIN_EDGES = 20
MAX_RUN_BITS = 10  # runs up to this long (in bits) fit the bit width; longer ones are idle or breaks
MIN_BIT_SAMPLES = 3  # fewer samples a bit cannot tell a bit's width (nor a UART decoder read it)


@dataclass
class Measurement:
    channel: str
    samplerate: int
    edges: int
    bit_samples: float  # the measured bit width
    measured_baud: float
    baud: int  # snapped to a standard rate when within SNAP
    fit: float  # share of short runs within a quarter bit of a whole number of bits
    inverted: bool
    chars: int = 0  # characters read
    pitch_bits: int | None = None  # shortest start-to-start inside a burst, in bits
    parity: str | None = None  # N, E, O (None: not told)
    stopbits: int | None = None
    parity_votes: dict = field(default_factory=dict)
    framing_errors: int = 0  # characters whose stop bit was low (at the format found)
    databits: int = 8

    @property
    def fmt(self) -> str:
        return f"{self.databits}{self.parity or '?'}{self.stopbits or '?'}"

    @property
    def settled(self) -> bool:
        return self.parity is not None and self.stopbits is not None and self.fit >= 0.9

    def describe(self) -> str:
        pol = ", idle low (inverted)" if self.inverted else ""
        pitch = f", characters {self.pitch_bits} bits apart in a burst" if self.pitch_bits else ""
        votes = ", ".join(f"{k} {v}" for k, v in self.parity_votes.items())
        return (f"bit {self.bit_samples:.2f} samples at {self.samplerate:,} Hz = {self.measured_baud:,.0f} baud "
                f"({self.fit:.0%} of {self.edges} edges on whole bits){pol}; {self.chars} characters read"
                f"{pitch}; bit 9 {votes}")


def _runs(edges: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """(level, length) of each whole run between two edges."""
    return [(edges[i][1], edges[i + 1][0] - edges[i][0]) for i in range(len(edges) - 1)]


def _bit_width(lengths: list[int]) -> tuple[float, float] | None:
    """(bit width in samples, fit) from run lengths; None if no width explains them."""
    short = sorted(x for x in lengths if x >= 2)
    if len(short) < MIN_EDGES // 2:
        return None
    need = max(3, len(short) // 50)
    b0 = None
    for i, r in enumerate(short):  # the shortest run length that many runs share (within 15 %): one bit
        j = i
        while j < len(short) and short[j] <= r * 1.15:
            j += 1
        if j - i >= need:
            b0 = sum(short[i:j]) / (j - i)
            break
    if b0 is None:
        return None
    bw = b0
    for _ in range(3):  # least squares through the origin over runs near whole multiples
        num = den = 0.0
        for x in short:
            k = round(x / bw)
            if 1 <= k <= MAX_RUN_BITS and abs(x / bw - k) < 0.25:
                num += x * k
                den += k * k
        if den == 0:
            return None
        bw = num / den
    if bw < MIN_BIT_SAMPLES:
        return None
    within = [x for x in short if x / bw <= MAX_RUN_BITS + 0.5]
    good = sum(1 for x in within if abs(x / bw - round(x / bw)) < 0.25)
    return bw, good / max(1, len(within))


def snap(baud: float) -> int:
    best = min(STANDARD_BAUDS, key=lambda b: abs(b - baud) / b)
    return best if abs(best - baud) / best <= SNAP else round(baud)


class _Wave:
    """The level (mark = 1) at any sample of a channel, from its edges."""

    def __init__(self, edges: list[tuple[int, int]], inverted: bool) -> None:
        self.samples = [s for s, _ in edges]
        self.levels = [v ^ inverted for _, v in edges]

    def at(self, sample: float) -> int:
        return self.levels[max(0, bisect_right(self.samples, sample) - 1)]


def measure(channel: str, edges: list[tuple[int, int]], rate: int) -> Measurement | None:
    if len(edges) < MIN_EDGES:
        return None
    runs = _runs(edges)[1:]
    width = _bit_width([n for _, n in runs])
    if width is None:
        return None
    bw, fit = width
    # idle: the level of the runs longer than a character (more of them, and longer, than breaks)
    long_high = sum(n for v, n in runs if v and n > 12 * bw)
    long_low = sum(n for v, n in runs if not v and n > 12 * bw)
    inverted = long_low > long_high
    m = Measurement(channel, rate, len(edges), bw, rate / bw, snap(rate / bw), fit, inverted)
    _characters(m, edges, bw)
    return m


def _characters(m: Measurement, edges: list[tuple[int, int]], bw: float) -> None:
    """Read each character at its bit centres: parity votes, pitch, stop bits."""
    wave = _Wave(edges, m.inverted)
    starts = []
    k = 0
    n = len(edges)
    while k < n:
        s, level = edges[k]
        if level ^ m.inverted == 0:  # a falling edge (in mark-high terms): a start bit
            bits = [wave.at(s + (b + 0.5) * bw) for b in range(12)]
            if bits[0] == 0:
                starts.append((s, bits))
                end = s + 9.5 * bw  # on from the middle of the earliest stop bit (8N1's), as a UART looks again
                while k < n and edges[k][0] < end:
                    k += 1
                continue
        k += 1
    m.chars = len(starts)
    if m.chars < 4:
        return
    even = odd = ones = 0
    for _, bits in starts:
        data_ones = sum(bits[1:9])
        even += (data_ones + bits[9]) % 2 == 0
        odd += (data_ones + bits[9]) % 2 == 1
        ones += bits[9] == 1
    m.parity_votes = {"even parity": even, "odd parity": odd, "high (a stop bit)": ones}
    pitches = [round((b[0] - a[0]) / bw) for a, b in zip(starts, starts[1:]) if (b[0] - a[0]) / bw < 13.5]
    if not pitches:
        return
    m.pitch_bits = min(p for p in pitches if p >= 10) if any(p >= 10 for p in pitches) else min(pitches)
    total = m.chars
    even7 = sum(1 for _, bits in starts if (sum(bits[1:8]) + bits[8]) % 2 == 0)
    bit8 = {bits[8] for _, bits in starts}
    most = 0.98 * total  # a few damaged characters (the capture cut one) do not hide the rule
    if ones >= most and (even7 >= most or total - even7 >= most) and len(bit8) == 2:
        # bit 9 a stop bit, bit 8 (both values seen) always the parity of bits 1-7: 7 data bits
        m.databits, m.parity = 7, "E" if even7 >= most else "O"
        m.parity_votes["bit 8 as the parity of 7 bits: even"] = even7
    elif ones == total and (even == total or odd == total):
        pass  # every character's data has one parity and bit 9 is high: a parity bit or a stop bit, not told
    elif even == total:
        m.parity = "E"
    elif odd == total:
        m.parity = "O"
    elif ones == total:
        m.parity = "N"
    elif max(even, odd, ones) >= 0.98 * total:  # a few damaged characters: the clear majority
        m.parity = "E" if even >= max(odd, ones) else "O" if odd >= ones else "N"
    if m.parity is None:
        return
    used = 1 + m.databits + (m.parity != "N")
    stop = m.pitch_bits - used
    m.stopbits = 2 if stop >= 2 else 1 if stop == 1 else None
    stop_at = used  # the first stop bit's index
    m.framing_errors = sum(1 for _, bits in starts if bits[stop_at] != 1)
