"""The order `sniffer detect` listens in, when a listen is long enough, and the verdict.  Sans-I/O.

    search = Search(baud_order(()))
    while (rx := search.next()) is not None:
        ... listen at rx, building a Window; stop when search.window_done(window.evidence(now)) ...
        search.add(evidence)
    search.verdict()

1. Find the baud rate: listen at 8N1 at each rate (the ones asked for first, then
   the common ones, most common first).  At the right rate a UART set to 8N1 gets
   the data bits of every 8-bit format right (a parity or second stop bit lands
   where it checks its stop bit: a framing error at worst), and a 7-bit ASCII line
   reads as text with its parity in bit 7; so some protocol frames the bytes.  A
   UART that takes a low stop bit for the next start bit garbles an 11-bit line
   read at 8N1; a second sweep at 8E1 (right for 11-bit lines) catches that.
2. At the rate found, try the formats, the one the bytes point to first
   (Evidence.hint: which bytes the tty marked, bit 7 of ASCII, the timing), the
   7-bit ones only if the line looks like ASCII.  The first *certain* candidate
   ends the search.  If none is certain, every format at that rate is tried and
   the verdict weighs what fits.
3. A listen ends when its candidate is certain, when it cannot fit (UART errors,
   characters too fast) or frames nothing, when it fits and has heard plenty,
   or after MAX_WINDOW_S (MAX_FORMAT_WINDOW_S once the rate is found).  The first
   listen waits up to `quiet_s` for a first byte.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from sniffer.line import LineSettings
from sniffer.detect.candidates import FORMATS_7, FORMATS_8, TWINS, fmt_of, setting
from sniffer.detect.evidence import FIT_ERRORS, Evidence

MIN_WINDOW_S = 0.2
MAX_WINDOW_S = 1.5
MAX_FORMAT_WINDOW_S = 3.0  # at a rate the bytes frame at: a slow line gets longer to show its frames
ENOUGH_CHARS = 400  # a fitting listen that heard this much is not going to change its mind
MIN_FRAME = 4  # no protocol's frame is shorter
HOPELESS_ERRORS = 0.3  # UART errors on this share of the bytes, and nothing framed: not this setting


@dataclass
class Verdict:
    status: str  # "certain", "fits", "stop bits", "several", "none", "no traffic"
    best: Evidence | None
    windows: list[Evidence]
    rivals: list[Evidence] = field(default_factory=list)  # the other candidates that fit
    decided_s: float = 0.0  # listening time until the verdict (without a follow-up listen for the units)

    @property
    def settled(self) -> bool:
        return self.status in ("certain", "fits", "stop bits")


class Search:
    def __init__(self, bauds: tuple[int, ...], *, quiet_s: float = 5.0) -> None:
        self.bauds = bauds
        self.quiet_s = quiet_s
        self.windows: list[Evidence] = []
        self._plan: deque[LineSettings] = deque(setting(b, "8N1") for b in bauds)
        self._second_sweep = True
        self._tried: set[tuple[int, str]] = set()
        self._found_baud: int | None = None
        self._formats_at_baud: list[str] = []
        self.finished = False

    def next(self) -> LineSettings | None:
        while self._plan and not self.finished:
            rx = self._plan.popleft()
            if (rx.baud, fmt_of(rx)) not in self._tried:
                return rx
        return None

    def window_done(self, ev: Evidence) -> bool:
        """Has the listen that gave `ev` heard enough?"""
        if ev.certain:
            return True
        if ev.chars == 0 and not self.windows:
            return ev.seconds >= self.quiet_s  # the first listen waits for the line to say something
        if ev.seconds >= (MAX_FORMAT_WINDOW_S if self._found_baud is not None else MAX_WINDOW_S):
            return True
        if ev.seconds < MIN_WINDOW_S:
            return False
        unfit = ev.errors > max(1, ev.chars * FIT_ERRORS) or ev.timing == "impossible"
        if ev.found:  # the rate is right: is the format?
            timing_coming = ev.fmt in TWINS and ev.timing == "?" and ev.timed_s > 0  # long frames: wait for it
            return ((unfit and ev.chars >= 60) or (ev.fits and ev.chars >= ENOUGH_CHARS and not timing_coming)
                    or (ev.best is None and ev.chars >= 100 and ev.bursts >= 4))
        nothing = ev.best is None
        garbage = nothing and ev.errors >= HOPELESS_ERRORS * ev.chars and (
            (ev.bursts >= 3 and ev.chars >= 16) or ev.chars >= 200)
        too_few = nothing and ev.bursts >= 2 and ev.chars < MIN_FRAME * ev.bursts  # a receiver slower than the line
        return garbage or too_few or (ev.bursts >= 5 and ev.pending <= ev.chars // 4)  # (unless still deciding)

    def add(self, ev: Evidence) -> None:
        self.windows.append(ev)
        self._tried.add((ev.rx.baud, ev.fmt))
        if ev.certain:
            self.finished = True
            return
        if ev.chars == 0 and len(self.windows) == 1:
            self.finished = True  # no traffic
            return
        baud = ev.rx.baud
        if self._found_baud is None and ev.found:
            self._found_baud = baud
            self._formats_at_baud = self._formats(ev)
            self._plan.extendleft(reversed([setting(baud, f) for f in self._formats_at_baud]))
        elif self._found_baud is None and ev.hint and (baud, ev.hint) not in self._tried:
            self._plan.appendleft(setting(baud, ev.hint))  # nothing framed, but the marks point somewhere
        elif self._found_baud == baud and all((baud, f) in self._tried for f in self._formats_at_baud):
            if any(w.fits for w in self.windows):
                self.finished = True  # every format at the rate tried: weigh what fits
                return
            self._found_baud = None  # a false start: go on with the rates
        if not any((rx.baud, fmt_of(rx)) not in self._tried for rx in self._plan) and self._second_sweep:
            self._second_sweep = False
            self._plan.extend(setting(b, "8E1") for b in self.bauds)

    def _formats(self, ev: Evidence) -> list[str]:
        """The formats to try at a rate the bytes frame at, the hinted one first."""
        text = ev.hint in FORMATS_7 or (ev.best is not None and ev.best.protocol.endswith("ascii"))
        formats = list(FORMATS_8) + (list(FORMATS_7) if text else [])
        if ev.hint in formats:
            formats.remove(ev.hint)
            formats.insert(0, ev.hint)
        return formats

    def verdict(self) -> Verdict:
        ws = self.windows
        if not any(w.chars or w.errors for w in ws):
            return Verdict("no traffic", None, ws)
        ranked = sorted(ws, key=rank, reverse=True)
        certain = [w for w in ranked if w.certain]
        if certain:
            return Verdict("certain", certain[0], ws)
        fitting = [w for w in ranked if w.fits]
        if not fitting:
            return Verdict("none", ranked[0], ws)
        best, rivals = fitting[0], fitting[1:]
        if not rivals:
            return Verdict("stop bits" if best.only_stop_bits_open else "fits", best, ws)
        if all(r.rx.baud == best.rx.baud and TWINS.get(best.fmt) == r.fmt and r.best.protocol == best.best.protocol
               for r in rivals):
            # a UART set to 1 stop bit reads both alike: that one, unless the timing said 2
            pick = min(fitting, key=lambda w: (not w.timing_tells_twins(), w.rx.stopbits))
            return Verdict("stop bits", pick, ws, [w for w in fitting if w is not pick])
        return Verdict("several", best, ws, rivals)


def rank(ev: Evidence) -> tuple:
    """Certain before fitting before the rest; then more bytes in fitting frames, fewer UART errors,
    timing that fits exactly, more pairs."""
    b = ev.best
    cover = b.coverage if b else 0.0
    err = ev.errors / ev.chars if ev.chars else 1.0
    timing = {"exact": 2, "?": 1, "slower": 1, "impossible": 0}[ev.timing]
    return (ev.certain, ev.fits, round(cover - err, 3), timing, b.pairs if b else 0)
