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

    def __post_init__(self) -> None:
        if self.kind not in BY_NAME:
            raise ValueError(f"unknown finding kind {self.kind!r}")
        self.frames = sorted(set(self.frames))[:MAX_FRAMES]

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
        }

    def headline(self) -> str:
        """One line: severity, kind, where, when."""
        span = "" if self.t_start is None else f"  {self.t_start:.1f}-{self.t_end:.1f} s"
        return f"{self.severity.upper():<8}{self.kind}  {self.where}{span}"

    def text_lines(self) -> list[str]:
        out = [self.headline(), f"  {self.text}"]
        if self.evidence:
            out.append("  evidence: " + ", ".join(f"{k.replace('_', ' ')} {fmt_value(v)}"
                                                  for k, v in self.evidence.items()))
        if self.statistic:
            out.append("  statistic: " + ", ".join(f"{k} {fmt_value(v)}" for k, v in self.statistic.items()))
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


def fmt_value(v) -> str:
    """A number (or a list or dict of them) for text: floats short, large and tiny ones in exponent form."""
    if isinstance(v, float):
        if v != 0 and (abs(v) < 0.001 or abs(v) >= 1e6):
            return f"{v:.2g}"
        return f"{v:.3f}".rstrip("0").rstrip(".")
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {fmt_value(x)}" for k, x in v.items()) + "}"
    return str(v)
