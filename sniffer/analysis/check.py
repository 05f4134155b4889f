"""`sniffer check`: a capture against its reviewed golden decode, compared line by line as it decodes.

The golden text has one line per frame:

    <t seconds> <latency ms or -> | <content: role, unit, model, fc, crc, pair offset, summary, codes>

A summary shows at most 6 points ("... (+N)"); v2 goldens add the rest after it
(" | rest: name=value ..."), so a value changed in the 7th register of a read
is a changed line too.  A v1 golden (no rest) is compared as v1.
A capture of several links starts each line's content with `link=NAME`.
A golden may hold the capture's findings too (`sniffer diagnose`'s verdicts, after the frames, one
line each: `finding <severity> <kind> link=<link> unit=<unit>`): written with `--update-golden
--findings`, and compared whenever the golden holds them (or --findings asks), so a change that
makes a verdict appear or vanish is a changed golden; the findings' numbers are not held.
Content is compared exactly; the two timing columns within tolerances
(`Tolerances(time_ms=..., latency_ms=...)`), so a golden survives a rounding
change in a clock model but not a changed verdict.  Exit codes: 0 same,
1 different (a unified diff), 2 error (unreadable capture, missing golden).

Streaming: the capture is decoded frame by frame and the golden read line by
line; only a window of unmatched lines is held while the two disagree (a
window of `WINDOW` lines each side is re-aligned with difflib), so a capture of
any length is checked in flat memory.  The diff shows at most `MAX_SHOWN`
changed lines and counts the rest.
"""

from __future__ import annotations

import os

import difflib
from collections import deque
from itertools import islice
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from sniffer.analysis.goldenfields import NO_RULES, FieldRules, Names, differences, parse
from sniffer.frame import Frame

EXIT_SAME, EXIT_DIFFERENT, EXIT_ERROR = 0, 1, 2
GOLDEN_HEADER = ("# sniffer golden v2: t_s latency_ms | role unit model fc crc pair(offset) summary [| rest: points "
                 "past the summary's 6] [codes]")
GOLDEN_V1 = "# sniffer golden v1: t_s latency_ms | role unit model fc crc pair(offset) summary [codes]"
SHOWN = 6  # points a summary shows (decoders.generic.decoder._points_summary)
WINDOW = 2000  # unmatched lines held per side while re-aligning
WINDOWS = (16, 256, WINDOW)  # the windows tried in turn: the cost of a realignment grows with its square
MAX_SHOWN = 2000  # changed lines shown in a diff (the rest are counted)
CONTEXT = 3


@dataclass(frozen=True)
class Tolerances:
    """Timing tolerances; content is always exact."""

    time_ms: float = 1.0  # frame start time
    latency_ms: float = 1.0  # request -> response latency
    rules: FieldRules = FieldRules()  # fields ignored or compared within a tolerance (--ignore, --tolerance)


def _rest(f: Frame) -> str:
    """The points a summary left out (" ... (+N)"), as name=value text: '' if it left none out."""
    if " ... (+" not in f.summary:
        return ""
    from decoders.generic.decoder import points_summary

    pts = f.points
    return f" | rest: {points_summary(list(pts[SHOWN:]), 1 << 30)}" if len(pts) > SHOWN else ""


def golden_line(f: Frame, t0_ns: int, version: int = 2) -> str:
    t = (f.t_ns - t0_ns) / 1e9
    lat = "-" if f.latency_ms is None else f"{f.latency_ms:.3f}"
    codes = ",".join(a.code for a in f.annotations)
    tail = f" [{codes}]" if codes else ""
    if f.protocol == "noise":
        content = f"NOISE {len(f.raw)}B {f.raw.hex()} ({f.noise_reason}){tail}"
    else:
        unit = "?" if f.unit is None else str(f.unit)
        fc = "--" if f.function is None else f"{f.function:02X}"
        crc = {True: "ok", False: "BAD", None: "-"}[f.crc_ok]
        # the partner as an offset, not an index: one inserted frame is one diff line
        pair = "-" if f.pair is None else f"{f.pair - f.index:+d}"
        rest = _rest(f) if version >= 2 else ""
        content = (f"{f.role} u{unit} {f.model or '-'} fc{fc} crc={crc} pair={pair} "
                   f"{f.summary}{rest}{tail}")
    if f.link:  # a capture of several links: which link the frame is on is content too
        content = f"link={f.link} {content}"
    return f"{t:.6f} {lat} | {content}"


def golden_lines(t0_ns: int, frames: Iterable[Frame], version: int = 2) -> Iterator[str]:
    """The golden text of a decode, line by line (header first); `version` 1 for an old golden."""
    yield GOLDEN_HEADER if version >= 2 else GOLDEN_V1
    for f in frames:
        yield golden_line(f, t0_ns, version)


def golden_text(t0_ns: int, frames: Iterable[Frame]) -> str:
    return "\n".join(golden_lines(t0_ns, frames)) + "\n"


def _split(line: str) -> tuple[float | None, float | None, str]:
    head, sep, content = line.partition(" | ")
    if not sep:
        return None, None, line
    try:
        t_s, lat_s = head.split(" ")
        return float(t_s), (None if lat_s == "-" else float(lat_s)), content
    except ValueError:
        return None, None, line


split_line = _split  # (t seconds, latency ms, content) of a golden line


def within(old: str, new: str, tol: Tolerances, names: Names | None = None) -> bool:
    """The same frame: content equal (but for the fields the rules leave out), timing within tolerance."""
    if old == new:
        return True
    t_a, l_a, c_a = _split(old)
    t_b, l_b, c_b = _split(new)
    if t_a is None or t_b is None:
        return False
    if c_a != c_b and not (tol.rules and not differences(parse(c_a, names), parse(c_b, names), tol.rules)):
        return False
    if abs(t_a - t_b) * 1e3 > tol.time_ms + 1e-9:
        return False
    if (l_a is None) != (l_b is None):
        return False
    return l_a is None or abs(l_a - l_b) <= tol.latency_ms + 1e-9


class _Diff:
    """Unified-diff hunks built as the two streams are walked (bounded output)."""

    def __init__(self, names: tuple[str, str]) -> None:
        self.names = names
        self.out: list[str] = []
        self.before: deque[str] = deque(maxlen=CONTEXT)  # equal lines before the next change
        self.hunk: list[str] | None = None
        self.h_old = self.h_new = 0  # hunk start line numbers (1-based)
        self.n_old = self.n_new = 0  # hunk sizes
        self.after = 0  # equal lines since the hunk's last change
        self.shown = 0
        self.hidden = 0

    def equal(self, line: str) -> None:
        if self.hunk is not None:
            if self.after < CONTEXT:
                self.hunk.append(" " + line)
                self.n_old += 1
                self.n_new += 1
                self.after += 1
                return
            self._close()
        self.before.append(line)

    def change(self, old: list[str], new: list[str], at_old: int, at_new: int) -> None:
        """Lines removed from the golden / added by the capture; at_* = line number of the first."""
        if self.hunk is None:
            self.hunk = [" " + x for x in self.before]
            self.h_old, self.h_new = at_old - len(self.before), at_new - len(self.before)
            self.n_old = self.n_new = len(self.before)
            self.before.clear()
        self.after = 0
        for prefix, lines in (("-", old), ("+", new)):
            for x in lines:
                if self.shown < MAX_SHOWN:
                    self.hunk.append(prefix + x)
                    self.shown += 1
                else:
                    self.hidden += 1
            if prefix == "-":
                self.n_old += len(lines)
            else:
                self.n_new += len(lines)

    def _close(self) -> None:
        if self.hunk is None:
            return
        if not self.out:
            self.out += [f"--- {self.names[0]}", f"+++ {self.names[1]}"]
        self.out.append(f"@@ -{_range(self.h_old, self.n_old)} +{_range(self.h_new, self.n_new)} @@")
        self.out += self.hunk
        self.hunk = None

    def text(self) -> str:
        self._close()
        if self.hidden:
            self.out.append(f"... {self.hidden} more changed lines not shown")
        return "\n".join(self.out) + "\n" if self.out else ""


def _range(start: int, n: int) -> str:
    return f"{start},{n}" if n != 1 else f"{start}"


def compare_lines(old: Iterable[str], new: Iterable[str], tol: Tolerances = Tolerances(),
                  names: tuple[str, str] = ("golden", "capture"), on_change=None,
                  point_names: Names | None = None, start: tuple[int, int] = (1, 1)) -> str:
    """'' when the two line streams agree within tolerance, else a unified diff (timing-only noise hidden).
    `on_change(old_lines, new_lines, at_old, at_new)` hears each changed block (the summary is built from
    them); `point_names` anchor the field rules' split of a line (sniffer.analysis.goldenfields); `start`: the
    file line numbers of the streams' first lines (the hunks name lines of the files)."""
    a_it, b_it = iter(old), iter(new)
    key = _keyer(tol.rules, point_names)
    a: deque[str] = deque()
    b: deque[str] = deque()
    a_end = b_end = False
    line_a, line_b = start  # line number of a[0], b[0]
    d = _Diff(names)

    def fill(buf, it, end, n):
        while not end and len(buf) < n:
            x = next(it, None)
            if x is None:
                return True
            buf.append(x)
        return end

    while True:
        a_end = fill(a, a_it, a_end, 1)
        b_end = fill(b, b_it, b_end, 1)
        if not a and not b:
            break
        if a and b and within(a[0], b[0], tol, point_names):
            d.equal(a.popleft())
            b.popleft()
            line_a += 1
            line_b += 1
            continue
        for size in WINDOWS:  # a small window first: most changes are a line or a few, realigned at once
            a_end = fill(a, a_it, a_end, size)
            b_end = fill(b, b_it, b_end, size)
            wa, wb = list(islice(a, size)), list(islice(b, size))
            got = _realign(wa, wb, a_end and len(wa) == len(a), b_end and len(wb) == len(b), key)
            if got is not None:
                break
        i, j = got if got is not None else (len(wa), len(wb))  # nothing agrees within WINDOW: all a change
        old_lines = [a.popleft() for _ in range(i)]
        new_lines = [b.popleft() for _ in range(j)]
        if not old_lines and not new_lines:  # same content, timing beyond tolerance
            old_lines, new_lines = [a.popleft()], [b.popleft()]
        d.change(old_lines, new_lines, line_a, line_b)
        if on_change is not None:
            on_change(old_lines, new_lines, line_a, line_b)
        line_a += len(old_lines)
        line_b += len(new_lines)
    return d.text()


def _keyer(rules: FieldRules, names: Names | None):
    """A line's alignment key: its content, without the fields the rules leave out or tolerate."""
    if not rules:
        return lambda line: _split(line)[2]
    from functools import lru_cache

    @lru_cache(maxsize=8192)  # a window is re-keyed at each change: most lines are keyed before
    def key(line: str) -> str:
        c = parse(_split(line)[2], names)
        kept = [f"{k}={v}" for k, v in c.fields.items() if not rules.ignored(k) and rules.tolerance_of(k) is None]
        return "\x1f".join((*c.key, *kept))
    return key


def _realign(a: list[str], b: list[str], a_end: bool, b_end: bool, key=None) -> tuple[int, int] | None:
    """How many lines of a and b differ before the two agree again (content keys, difflib); None if they do
    not agree again within a and b."""
    key = key or (lambda line: _split(line)[2])
    ka = [key(x) for x in a]
    kb = [key(x) for x in b]
    sm = difflib.SequenceMatcher(None, ka, kb, autojunk=False)
    for i, j, n in sm.get_matching_blocks():
        reaches_end = i + n == len(a) and j + n == len(b) and a_end and b_end
        if n >= CONTEXT or (n and reaches_end):
            return i, j
    return None


def compare_text(old: str, new: str, tol: Tolerances = Tolerances(), names=("golden", "capture")) -> str:
    """compare_lines over two texts."""
    return compare_lines(old.splitlines(), new.splitlines(), tol, names)


OPTIONS = "# sniffer check options: "  # a golden's second header line: the tolerances it is checked with


def options_line(tol: Tolerances) -> str | None:
    """The header line that keeps `tol` with the golden (None when every tolerance is the default)."""
    import orjson

    d: dict = {}
    if tol.time_ms != Tolerances.time_ms:
        d["time_tol_ms"] = tol.time_ms
    if tol.latency_ms != Tolerances.latency_ms:
        d["latency_tol_ms"] = tol.latency_ms
    d.update(tol.rules.to_json())
    return OPTIONS + orjson.dumps(d).decode() if d else None


def golden_tolerances(path: Path) -> dict:
    """The options a golden's header keeps ({} if none): time_tol_ms, latency_tol_ms, rules (FieldRules)."""
    import orjson

    for line in read_lines(path):  # a FIFO, a device, a folder: one line (sniffer.inputs)
        if not line.startswith("#"):
            break
        if line.startswith(OPTIONS):
            try:
                d = orjson.loads(line[len(OPTIONS):])
                if not isinstance(d, dict):
                    raise ValueError("not an object")
                d["rules"] = FieldRules.from_json(d)
            except ValueError as e:
                raise ValueError(f"{path}: unreadable options line in the header ({e})") from None
            return d
    return {}


def resolve(path: Path | None, time_ms: float | None, latency_ms: float | None,
            rules: FieldRules = NO_RULES) -> Tolerances:
    """The tolerances of a check: the command line's, else the golden header's, else the defaults; the
    field rules of both (the command line's tolerance wins for the same field)."""
    kept = golden_tolerances(path) if path is not None and path.exists() else {}
    return Tolerances(
        time_ms=next(v for v in (time_ms, kept.get("time_tol_ms"), Tolerances.time_ms) if v is not None),
        latency_ms=next(v for v in (latency_ms, kept.get("latency_tol_ms"), Tolerances.latency_ms) if v is not None),
        rules=kept.get("rules", FieldRules()).merged(rules))


def golden_version(path: Path) -> int:
    """The golden format of the file at path: 1 for a v1 header, else the current one."""
    return 1 if next(read_lines(path), None) == GOLDEN_V1 else 2


FINDING = "finding "  # a golden line holding a verdict (after the frames)


def read_lines(path: Path) -> Iterator[str]:
    """The golden's lines, streamed; a FIFO, a device, a folder or a line over 1 MB: InputError (one line)."""
    from sniffer.inputs import read_lines as regular_lines

    lines = regular_lines(os.fspath(path), "a golden file")
    try:
        yield from lines
    finally:
        lines.close()
