"""One listen at one setting (baud rate and format), and the evidence it gives.  Sans-I/O.

    w = Window(LineSettings(19200, "E", 1), t_ns)
    w.feed(t_ns, data)      # each read, as the tty handed it over (PARMRK marks in it)
    w.tick(t_ns)            # silence: lets the framers close frames
    ev = w.evidence()       # Evidence: errors, frames per protocol, pairs, timing, units

The bytes up to the first silence are dropped: the listen may have started in the
middle of a frame, and what came in the first SETTLE_NS may have been received at
the old setting (a line that is never silent for START_ANYWAY_NS is taken as it
comes).  Only frames the framers have settled count: a listen ends in the middle
of a frame, and that one is neither evidence for nor against.  Every protocol's framer and a pairer read the rest
(`Reading`); a frame *fits* when its CRC/LRC is good and nothing says its shape is
wrong for the protocol (`MISFIT`), a pair fits when the pairer pairs a fitting
response with its request.  An 8-bit listen also gives hints for the search: the
ASCII protocols read with the top bit stripped (a 7-bit line read at 8 bits), the
popcounts of the bytes the tty marked (a parity line read without parity marks
those whose parity bit is 0), and the timing (evidence.py).
"""

from __future__ import annotations

from sniffer.events import Chunk
from sniffer.line import LineSettings
from sniffer.sources.parmrk import NUL_ERROR, MarkReader
from sniffer.protocols import PROTOCOLS
from sniffer.detect.evidence import Evidence, Reading

SILENCE_MIN_NS = 2_000_000  # a read this long after the previous one ends the bytes dropped at the start
BURST_GAP_NS = 10_000_000  # bursts are counted at gaps this long (a host can take a read 5 ms late)
SETTLE_NS = 20_000_000  # bytes read this soon after the setting changed may have come at the old one
START_ANYWAY_NS = 200_000_000  # a line that is never silent this long: start anyway


class Window:
    def __init__(self, rx: LineSettings, t0_ns: int) -> None:
        self.rx = rx
        self.t0_ns = t0_ns
        self.t_last_ns = t0_ns  # the last read, or the start
        self.gap_ns = max(SILENCE_MIN_NS, rx.t35_ns)
        self.burst_gap_ns = max(BURST_GAP_NS, rx.t35_ns)
        self.started = False
        self.skipped = 0  # bytes before the first silence
        self.bursts = 0  # runs of reads between silences
        self.chars = 0
        self.errors = 0
        self.nul_errors = 0
        self.reads: list[tuple[int, int]] = []  # (time, chars received up to the end of this read)
        self.popcounts = [[0, 0], [0, 0]]  # [unmarked, marked] x [even, odd] popcount of the byte
        self._marks = MarkReader()
        self.readings = {name: Reading(p, rx) for name, p in PROTOCOLS.items()}
        # hints: the text protocols on the bytes with the top bit stripped (a 7-bit line read at 8 bits)
        self.hints = ({name: Reading(p, rx, mask=0x7F) for name, p in PROTOCOLS.items() if p.text}
                      if rx.databits == 8 else {})
        self.top_bits = [0, 0, 0]  # bytes whose bit 7 is 1, is the even parity of bits 0-6, is the odd one

    def feed(self, t_ns: int, raw: bytes) -> None:
        data, marks = self._marks.feed(raw)
        if not self.started:
            if t_ns - self.t0_ns < SETTLE_NS or (t_ns - self.t_last_ns < self.gap_ns
                                                 and t_ns - self.t0_ns < START_ANYWAY_NS):
                self.skipped += len(data)
                self.t_last_ns = t_ns
                return
            self.started = True
        if t_ns - self.t_last_ns >= self.burst_gap_ns or not self.bursts:
            self.bursts += 1
        self.t_last_ns = t_ns
        if not data:
            return
        marked = {off for off, _ in marks}
        self.errors += len(marks)
        self.nul_errors += sum(1 for _, kind in marks if kind == NUL_ERROR)
        for i, b in enumerate(data):
            self.popcounts[i in marked][bin(b).count("1") & 1] += 1
            low = bin(b & 0x7F).count("1") & 1
            self.top_bits[0] += b >> 7
            self.top_bits[1] += (b >> 7) == low
            self.top_bits[2] += (b >> 7) != low
        self.chars += len(data)
        self.reads.append((t_ns, self.chars))
        chunk = Chunk(t_ns, data)
        for r in (*self.readings.values(), *self.hints.values()):
            r.feed(chunk)

    def tick(self, t_ns: int) -> None:
        if not self.started and t_ns - self.t0_ns >= SETTLE_NS and t_ns - self.t_last_ns >= self.gap_ns:
            self.started = True  # silence: what comes next starts a burst
        for r in (*self.readings.values(), *self.hints.values()):
            r.tick(t_ns)

    def evidence(self, t_ns: int) -> Evidence:
        return Evidence.of(self, t_ns)
