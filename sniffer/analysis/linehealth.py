"""Do the line's frames look like the settings are right?  A sliding judgement over the frames, sans-I/O.

    watch = LineWatch()
    for frame in frames:
        change = watch.frame(frame)      # None, or a Change: a line broke (say it once), or recovered

A UART at the wrong baud rate, parity or stop bits still delivers bytes, only the wrong ones: the
frame list fills with CRC errors, parity and framing errors and noise.  `LineHealth` says so from
the frames alone (a time and three facts each), so the capture's stderr (`LineWarning`, a sink) and
the TUI judge alike.  The rule:

* a frame is *bad* when it is noise, its CRC or LRC does not match (or is unproven), or one of its
  bytes came with a UART error (framing or parity);
* the window is the frames of the last WINDOW_S seconds of capture time, at most MAX_FRAMES of them
  (a fast line is judged on its last MAX_FRAMES frames);
* broken (`most`): the window holds at least MIN_FRAMES frames and MIN_BYTES bytes over at least
  MIN_SPAN_S (or MAX_FRAMES frames: a fast line), and more than
  BROKEN_SHARE of its frames *and* of its bytes are bad.  Both: one long noise burst among a slow
  poll's small good frames is most of the bytes but not of the frames; a few bad frames among many
  are neither.  A capture that starts in the middle of a frame starts with one noise frame: one
  bad frame of MIN_FRAMES is far from most;
* recovered (only once broken): the window holds the same minimum and at most RECOVERED_SHARE of
  its frames and of its bytes are bad.  Between the two shares the state stays as it was, so a line
  hovering near half bad does not say it again and again;
* a quiet line decides nothing: a window short of the minimum keeps the state it has.

Broken is said once, and again only after the line has recovered.  A capture of several links judges
each link on its own (`LineWatch`, keyed by `Frame.link`).  A healthy line with a few errors (the
simulator's `errors` scenario: about one frame in ten) stays far below BROKEN_SHARE.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from decoders.registry import code_book
from sniffer import codes
from sniffer.hot import HOT
from sniffer.sinks.base import Sink

WINDOW_S = 5.0
MAX_FRAMES = 200
MIN_FRAMES = 8
MIN_BYTES = 32
MIN_SPAN_S = 1.0  # a burst of noise as the capture starts (a unit booting) is not yet "the first seconds"
BROKEN_SHARE = 0.5  # more than this share bad: broken
RECOVERED_SHARE = 0.25  # at most this share bad: recovered
PROBABLY_WRONG = "are probably wrong; "  # in every warning (is_line_warning: the TUI knows the capture's by it)

_UART = code_book().in_category(codes.UART_CAT)
_NS = 1_000_000_000
CRC, UART, NOISE = 0, 1, 2  # what made a frame bad (a frame counts once, as the first that applies: noise, UART, CRC)
KINDS = ("CRC", "UART", "noise")


def badness(frame) -> int | None:
    """Why a frame is bad (NOISE, UART or CRC), or None for a good one."""
    if frame.protocol == "noise":
        return NOISE
    if frame.crc_ok is not False and frame.crc_ok is not None:
        return None  # a good CRC over bytes with a UART error is unproven (crc_ok False): no UART error here
    for a in frame.annotations:
        if a.code in _UART:
            return UART
    return CRC if frame.crc_ok is False else None


@dataclass(frozen=True)
class Change:
    """The line broke (`broken`) or recovered, with what the window held then."""

    broken: bool
    link: str
    frames: int
    bad: int
    nbytes: int
    bad_bytes: int
    span_s: float
    kinds: tuple[int, int, int]  # bad frames by kind: CRC, UART, noise

    def describe(self) -> str:
        """`38 of 40 frames (95% of the bytes) in 2.1 s are CRC errors, UART errors or noise (UART 30, CRC 8)`."""
        by = ", ".join(f"{KINDS[k]} {n}" for k, n in sorted(enumerate(self.kinds), key=lambda x: -x[1]) if n)
        share = self.bad_bytes / self.nbytes if self.nbytes else 0.0
        return (f"{self.bad} of {self.frames} frames ({share:.0%} of the bytes) in {self.span_s:.1f} s are CRC "
                f"errors, UART errors or noise ({by})")


class LineHealthPy:
    """One line's judgement (see the module doc): feed it every frame in time order.  The reference:
    LineHealth is the compiled copy of it where sniffer._hot is built (tests/test_hot_equal.py)."""

    def __init__(self, link: str = "", *, window_s: float = WINDOW_S, max_frames: int = MAX_FRAMES) -> None:
        self.link = link
        self.window_ns = int(window_s * _NS)
        self.min_span_ns = int(min(MIN_SPAN_S, window_s) * _NS)
        self._win: deque[tuple[int, int, int | None]] = deque(maxlen=max_frames)  # (t_ns, bytes, badness)
        self.frames = self.nbytes = self.bad = self.bad_bytes = 0
        self.kinds = [0, 0, 0]
        self.broken = False
        self.warnings = 0  # how often it broke

    def add(self, t_ns: int, nbytes: int, bad: int | None) -> Change | None:
        """One frame (its start time, its size, badness() of it); a Change when the state changes."""
        win = self._win
        if len(win) == win.maxlen:
            self._drop(win[0])  # the deque drops it on append
        win.append((t_ns, nbytes, bad))
        self.frames += 1
        self.nbytes += nbytes
        if bad is not None:
            self.bad += 1
            self.bad_bytes += nbytes
            self.kinds[bad] += 1
        if win[0][0] <= t_ns - self.window_ns:
            self._expire(t_ns)
        return self.judge()

    def advance(self, t_ns: int) -> None:
        """Capture time went on without a frame: the window slides (it only ever decides on a frame)."""
        self._expire(t_ns)

    def _expire(self, t_ns: int) -> None:
        win = self._win
        while win and win[0][0] <= t_ns - self.window_ns:
            self._drop(win.popleft())

    def _drop(self, item: tuple[int, int, int | None]) -> None:
        _, nbytes, bad = item
        self.frames -= 1
        self.nbytes -= nbytes
        if bad is not None:
            self.bad -= 1
            self.bad_bytes -= nbytes
            self.kinds[bad] -= 1

    def enough(self) -> bool:
        """The window holds enough to judge (a quiet line's does not)."""
        win = self._win
        return (self.frames >= MIN_FRAMES and self.nbytes >= MIN_BYTES
                and (win[-1][0] - win[0][0] >= self.min_span_ns or len(win) == win.maxlen))

    def most_bad(self) -> bool:
        return self.bad > BROKEN_SHARE * self.frames and self.bad_bytes > BROKEN_SHARE * self.nbytes

    def mostly_good(self) -> bool:
        return self.bad <= RECOVERED_SHARE * self.frames and self.bad_bytes <= RECOVERED_SHARE * self.nbytes

    def judge(self) -> Change | None:
        """The state after the last frame: a Change when it changed (the shares first: the common case ends there)."""
        if not self.broken:
            if not self.most_bad() or not self.enough():
                return None
            self.broken = True
            self.warnings += 1
            return self._change()
        if not self.mostly_good() or not self.enough():
            return None
        self.broken = False
        return self._change()

    def _change(self) -> Change:
        return _change(self, self._win)

    def window(self) -> list[tuple[int, int, int | None]]:
        """The window's (t_ns, nbytes, badness), oldest first."""
        return list(self._win)


def _change(h, win) -> Change:
    span = (win[-1][0] - win[0][0]) / _NS if win else 0.0
    return Change(h.broken, h.link, h.frames, h.bad, h.nbytes, h.bad_bytes, span, (h.kinds[0], h.kinds[1], h.kinds[2]))


if HOT is None:
    LineHealth = LineHealthPy
else:
    class LineHealth(HOT.Health):
        """LineHealthPy with its window and counters in C (sniffer/_hot.c Health): the same judgement,
        at a few C calls a frame.  A window the C type does not keep (more than 4096 frames, times past
        2**61 ns) is a LineHealthPy from the start; an unusual frame (a time past 2**61, a float) hands
        the state to a LineHealthPy, which runs from then on (_hand_over)."""

        def __new__(cls, link: str = "", *, window_s: float = WINDOW_S, max_frames: int = MAX_FRAMES):
            try:
                window_ns, min_span_ns = int(window_s * _NS), int(min(MIN_SPAN_S, window_s) * _NS)
            except (TypeError, ValueError, OverflowError):
                return LineHealthPy(link, window_s=window_s, max_frames=max_frames)  # it says what is wrong
            if (type(max_frames) is not int or not 1 <= max_frames <= 4096 or not 0 <= window_ns <= 2**61
                    or not 0 <= min_span_ns <= 2**61):
                return LineHealthPy(link, window_s=window_s, max_frames=max_frames)
            self = super().__new__(cls)
            self.max_frames = max_frames
            super().__init__(self, link, window_ns, min_span_ns, max_frames, MIN_FRAMES, MIN_BYTES, BROKEN_SHARE,
                             RECOVERED_SHARE)
            return self

        def __init__(self, link: str = "", *, window_s: float = WINDOW_S, max_frames: int = MAX_FRAMES) -> None:
            pass  # made in __new__ (which may give a LineHealthPy instead)

        def _change(self) -> Change:
            return _change(self, self.window())

        def _hand_over(self) -> LineHealthPy:
            py = LineHealthPy.__new__(LineHealthPy)
            py.link, py.window_ns, py.min_span_ns = self.link, self.window_ns, self.min_span_ns
            py._win = deque(self.window(), maxlen=self.max_frames)
            py.frames, py.nbytes, py.bad, py.bad_bytes = self.frames, self.nbytes, self.bad, self.bad_bytes
            py.kinds, py.broken, py.warnings = self.kinds, self.broken, self.warnings
            return py


class LineWatch:
    """Every link's LineHealth, fed the capture's frames (a capture of one line has the link "")."""

    health = LineHealth  # what judges a link: LineHealthPy for the reference (tests/test_hot_equal.py)

    def __init__(self) -> None:
        self.lines: dict[str, LineHealth] = {}

    def frame(self, f) -> Change | None:
        return self.add(f.link or "", f.t_ns, len(f.raw), badness(f))

    def add(self, link: str, t_ns: int, nbytes: int, bad: int | None) -> Change | None:
        """A frame by what counts of it (a frame of a part decoded elsewhere: sniffer.parallel)."""
        h = self.lines.get(link)
        if h is None:
            h = self.lines[link] = self.health(link)
        return h.add(t_ns, nbytes, bad)

    def broken(self) -> list[str]:
        """The links broken now."""
        return [link for link, h in self.lines.items() if h.broken]


def warning_text(change: Change, settings: str, hint: str) -> str:
    """The warning's one line (without `warning: `): what was seen, that the settings are probably wrong
    (`settings`: the ones the line is read with, e.g. `19200 8E1`), and `hint`: what to do."""
    where = f"link {change.link}: " if change.link else ""
    at = f" ({settings})" if settings else ""
    return f"{where}{change.describe()}: the line settings{at} {PROBABLY_WRONG}{hint}"


def is_line_warning(text: str) -> bool:
    """Is this line (a capture's stderr) the warning warning_text wrote?"""
    return "the line settings" in text and PROBABLY_WRONG in text


class LineWarning(Sink):
    """The capture's warning on stderr: a LineWatch over the frames that says each break once, as one line.

    `hint(info, link)` says what to do (sniffer.detect.hint); `say` writes the line (sniffer.stderr.say)."""

    split = "health"  # by parts: a few numbers a frame cross, the warning itself runs in the coordinator
    # frame_py in C (sniffer/_hot.c health_frame) for a link whose LineHealth runs in C; None: frame_py only
    _compiled_frame = staticmethod(HOT.health_frame) if HOT is not None else None

    def __init__(self, hint: Callable[[object, str], str], say: Callable[[str], None]) -> None:
        self.hint = hint
        self.say = say
        self.watch = LineWatch()
        self.info = None

    def start(self, info) -> None:
        self.info = info

    def frame(self, f) -> None:
        compiled = self._compiled_frame
        if compiled is not None:
            change = compiled(self.watch.lines, f, _UART)
            if change is not NotImplemented:
                if change is not None and change.broken:
                    self._say(change)
                return
        self.frame_py(f)

    def frame_py(self, f) -> None:
        """The reference of frame()."""
        self.observe(f.link or "", f.t_ns, len(f.raw), badness(f))

    def observe(self, link: str, t_ns: int, nbytes: int, bad: int | None) -> None:
        """A frame by what counts of it (LineWatch.add)."""
        change = self.watch.add(link, t_ns, nbytes, bad)
        if change is not None and change.broken:
            self._say(change)

    def _say(self, change: Change) -> None:
        self.say("warning: " + warning_text(change, line_settings(self.info, change.link),
                                            self.hint(self.info, change.link)))


def line_settings(info, link: str = "") -> str:
    """The settings a line is read with, `19200 8E1` (a link of several: its own), '' when not known."""
    if info is None:
        return ""
    d = next((x for x in info.links if x.get("name") == link), None) if link else None
    get = d.get if d is not None else (lambda k: getattr(info, k, None))
    baud = get("baud")
    if not baud:
        return ""
    return f"{baud} {get('databits') or 8}{get('parity') or 'N'}{get('stopbits') or 1}"
