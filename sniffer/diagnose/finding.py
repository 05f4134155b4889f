"""A finding: what is wrong (or worth knowing), where, since when, on what evidence, and what to do.

    Finding(kind="unit_silent", severity="error", unit=9, t_start=0.4, t_end=59.8,
            evidence={"requests": 200, "retries": 400}, frames=[12, 15, 18],
            text="Unit 9 never answered ...", action="Check that a drive is set to address 9 ...")

`to_dict()` is one object of `sniffer diagnose --format json`'s `{"findings": [...]}`; `text_lines()`
what the text output, the TUI and `check`'s golden show.  `sort(findings)` puts them most severe
first (then in the order of the kinds table, then by link and unit).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sniffer.diagnose.episodes import Episode, keep, words
from sniffer.diagnose.kinds import BY_NAME, ORDER, SEVERITY_RANK

MAX_FRAMES = 8  # frames named per finding


@dataclass
class Finding:
    kind: str
    severity: str
    text: str  # one sentence, in words
    action: str  # what to do
    unit: int | None = None  # None: the whole line
    link: str = ""  # a capture of several links: the link's name
    t_start: float | None = None  # seconds from the capture's start
    t_end: float | None = None
    evidence: dict = field(default_factory=dict)  # numbers: counts, rates, quantiles
    frames: list[int] = field(default_factory=list)  # frame numbers to look at
    statistic: dict | None = None  # where the verdict rests on one: {"test", "value", "p", ...}
    episodes: list[Episode] = field(default_factory=list)  # when it happened (episodes.py), first and last kept
    episode_count: int = 0  # how many episodes in all (more than `episodes` lists when it came often)

    def __post_init__(self) -> None:
        if self.kind not in BY_NAME:
            raise ValueError(f"unknown finding kind {self.kind!r}")
        self.frames = sorted(set(self.frames))[:MAX_FRAMES]
        self.episode_count = max(self.episode_count, len(self.episodes))
        self.episodes = keep(self.episodes)

    @property
    def where(self) -> str:
        unit = "the line" if self.unit is None else f"unit {self.unit}"
        return f"{self.link}: {unit}" if self.link else unit

    def sort_key(self) -> tuple:
        return (SEVERITY_RANK[self.severity], ORDER[self.kind], self.link, -1 if self.unit is None else self.unit)

    def to_dict(self) -> dict:
        return {
            "kind": self.kind, "severity": self.severity, "link": self.link or None, "unit": self.unit,
            "t_start": _round(self.t_start), "t_end": _round(self.t_end), "text": self.text, "action": self.action,
            "evidence": self.evidence, "frames": self.frames, "statistic": self.statistic,
            "episodes": [e.to_dict() for e in self.episodes], "episode_count": self.episode_count,
        }

    def when(self) -> str:
        """Its episodes in words ('' when none were judged)."""
        return words(self.episodes, self.episode_count)

    def headline(self) -> str:
        """One line: severity, kind, where, when."""
        span = "" if self.t_start is None else f"  {self.t_start:.1f}-{self.t_end:.1f} s"
        return f"{self.severity.upper():<8}{self.kind}  {self.where}{span}"

    def text_lines(self) -> list[str]:
        out = [self.headline(), f"  {self.text}"]
        if self.episodes:
            out.append(f"  when: {self.when()}")
        if self.evidence:
            out.append("  evidence: " + evidence_words(self.evidence))
        if self.statistic:
            out.append("  statistic: " + evidence_words(self.statistic))
        if self.frames:
            out.append("  frames: " + " ".join(f"#{i}" for i in self.frames))
        out.append(f"  do: {self.action}")
        return out

    def golden_line(self) -> str:
        """The verdict alone (kind, severity, where): what `check` holds in a golden, not the numbers."""
        unit = "-" if self.unit is None else self.unit
        return f"finding {self.severity} {self.kind} link={self.link or '-'} unit={unit}"


def sort(findings: list[Finding]) -> list[Finding]:
    return sorted(findings, key=Finding.sort_key)


def _round(v: float | None) -> float | None:
    return None if v is None else round(v, 3)


MAX_ITEMS = 6  # of a list or table named in text; the rest is in --format json


def evidence_words(ev: dict) -> str:
    """'requests 200, retries 400, refusals: fc03 3000H x2 (12 requests, 12 refused, exception 02H)'."""
    return ", ".join(f"{k.replace('_', ' ')}{':' if isinstance(v, (dict, list, tuple)) and v else ''} "
                     f"{fmt_value(v)}" for k, v in ev.items())


def fmt_value(v) -> str:
    """A value for people: floats short (large and tiny ones in exponent form), nothing as 'none', yes/no, a
    list as its items and a table as 'name (field value, ...)'; long ones summarised ('6 of 18 shown, the
    rest in --format json').  Never Python's own spelling of a dict, list or None."""
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if v != 0 and (abs(v) < 0.001 or abs(v) >= 1e6):
            return f"{v:.2g}"
        return f"{v:.3f}".rstrip("0").rstrip(".")
    if isinstance(v, (list, tuple)):
        items = [fmt_value(x) for x in v[:MAX_ITEMS]]
        return _more("; ".join(items) if any(isinstance(x, dict) for x in v) else ", ".join(items), len(v))
    if isinstance(v, dict):
        items = list(v.items())[:MAX_ITEMS]
        parts = [f"{k.replace('_', ' ') if isinstance(k, str) else k} "
                 f"{'(' + fmt_value(x) + ')' if isinstance(x, dict) else fmt_value(x)}" for k, x in items]
        return _more(", ".join(parts), len(v))
    return str(v)


def _more(text: str, n: int) -> str:
    if not n:
        return "none"
    return text if n <= MAX_ITEMS else f"{text} ({MAX_ITEMS} of {n} shown, the rest in --format json)"


def count_of(n: int, word: str, plural: str | None = None) -> str:
    """'1 unit', '3 units', '0 units': a count in words (no "unit(s)" in what people read)."""
    return f"{n} {word if n == 1 else plural or word + 's'}"
