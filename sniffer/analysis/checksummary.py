"""What a failing `check` says first: a summary that fits a screen, built from the changed blocks.

    frames: 68 of 278 differ (0 added, 0 missing)
    first: frame 3 at 0.150155 s, u1 fc03 response: Output current 10.0 A -> 12.5 A
    by unit and field: u1 Output current 68, ...
    findings: 1 added, 1 gone (compared as sets)

`Collector.change` hears each block of lines compare_lines found different; it pairs the block's lines by
who they are (link, role, unit, function), so a changed value is one changed frame and an inserted poll
is one added frame, and names the fields that differ (sniffer.analysis.goldenfields).  Findings (the
golden's `finding ...` lines) are compared as multisets: an order that changed is no difference.
The counts are streamed: memory holds the groups and the first difference, not the frames.
"""

from __future__ import annotations

import difflib
from collections import Counter
from dataclasses import dataclass, field

from collections.abc import Iterable, Iterator
from itertools import chain

from sniffer.analysis.check import FINDING, Tolerances, compare_lines, split_line
from sniffer.analysis.goldenfields import Content, FieldRules, Names, differences, parse

GROUPS_SHOWN = 6  # unit/field rows of the text summary (JSON has them all)


@dataclass
class FirstDifference:
    frame: int  # the capture's frame number (0-based, as replay and the TUI number them)
    t_s: float | None
    unit: str
    function: str
    role: str
    link: str
    kind: str  # changed | added | missing
    fields: list[tuple[str, str, str]]  # (field, golden value, capture value)

    def text(self) -> str:
        who = f"{'link ' + self.link + ' ' if self.link else ''}u{self.unit} fc{self.function} {self.role}"
        at = f"frame {self.frame}" + (f" at {self.t_s:.6f} s" if self.t_s is not None else "")
        if self.kind != "changed":
            return f"first: {at}, {who}: {self.kind}"
        shown = "; ".join(f"{n} {_short(o)} -> {_short(v)}" for n, o, v in self.fields[:2])
        more = f" (+{len(self.fields) - 2} more fields)" if len(self.fields) > 2 else ""
        return f"first: {at}, {who}: {shown}{more}"

    def to_dict(self) -> dict:
        return {"frame": self.frame, "t_s": self.t_s, "unit": self.unit, "function": self.function,
                "role": self.role, "link": self.link or None, "kind": self.kind,
                "fields": [{"field": n, "golden": o, "capture": v} for n, o, v in self.fields]}


def _short(value: str, n: int = 40) -> str:
    value = value or "(none)"
    return value if len(value) <= n else value[: n - 3] + "..."


@dataclass
class CheckSummary:
    golden: str
    capture: str
    golden_frames: int = 0
    capture_frames: int = 0
    changed: int = 0
    added: int = 0
    missing: int = 0
    first: FirstDifference | None = None
    groups: Counter = field(default_factory=Counter)  # (unit label, field) -> frames
    findings_golden: Counter = field(default_factory=Counter)
    findings_capture: Counter = field(default_factory=Counter)
    diff: str = ""  # the unified diff (shown with --diff)
    unmatched: list[str] = field(default_factory=list)  # --ignore/--tolerance rules no field of the capture matches
    known: set[str] = field(default_factory=set, repr=False)  # the capture's field names (for "did you mean")

    @property
    def findings_added(self) -> list[str]:
        return sorted((self.findings_capture - self.findings_golden).elements())

    @property
    def findings_gone(self) -> list[str]:
        return sorted((self.findings_golden - self.findings_capture).elements())

    @property
    def same(self) -> bool:
        return not (self.changed or self.added or self.missing or self.findings_added or self.findings_gone)

    def ok_line(self) -> str:
        n = sum(self.findings_golden.values())
        return f"ok: {self.capture_frames} frames, {n} findings match\n" + self.unmatched_text()

    def unmatched_text(self) -> str:
        """A note per --ignore/--tolerance rule that matched no field (a mistyped name ignores nothing)."""
        from sniffer.stderr import did_you_mean

        return "".join(f"note: --ignore/--tolerance {p!r} matched no field of the capture"
                       f"{did_you_mean(p, sorted(self.known))}\n" for p in self.unmatched)

    def headline(self) -> str:
        # of the frames in either: the golden's, and those only the capture has (changed + missing <= golden)
        return (f"{self.changed + self.added + self.missing} of {self.golden_frames + self.added} frames differ "
                f"({self.changed} changed, {self.added} added, {self.missing} missing)")

    def text(self, with_diff: bool = False, hint: str = "") -> str:
        out = [f"sniffer check: {self.capture} differs from {self.golden}", f"  frames: {self.headline()}"]
        if self.first is not None:
            out.append("  " + self.first.text())
        if self.groups:
            out.append("  by unit and field (frames):")
            rows = self.groups.most_common()
            for (unit, name), n in rows[:GROUPS_SHOWN]:
                out.append(f"    {unit:<5} {_short(name, 48):<48} {n}")
            if len(rows) > GROUPS_SHOWN:
                out.append(f"    ... {len(rows) - GROUPS_SHOWN} more (--format json lists them all)")
        out.append("  " + self._findings_text())
        out += ["  " + line for line in self.unmatched_text().splitlines()]
        if with_diff:
            return "\n".join(out) + "\n" + self.diff
        out.append(hint or "  --diff shows the unified diff; `sniffer diff` compares two captures in the drives' terms")
        return "\n".join(out) + "\n"

    def _findings_text(self) -> str:
        added, gone = self.findings_added, self.findings_gone
        if not (added or gone):
            n = sum(self.findings_golden.values())
            if not n:
                return "findings: none in the golden (--findings with --update-golden keeps them)"
            return f"findings: {n} match (compared as a set)"
        parts = []
        for word, items in (("added", added), ("gone", gone)):
            if items:
                shown = ", ".join(_finding_short(x) for x in items[:3]) + (" ..." if len(items) > 3 else "")
                parts.append(f"{len(items)} {word} ({shown})")
        return "findings: " + "; ".join(parts)

    def to_dict(self) -> dict:
        return {
            "golden": self.golden, "capture": self.capture, "same": self.same,
            "frames": {"golden": self.golden_frames, "capture": self.capture_frames,
                       "differ": self.changed + self.added + self.missing, "changed": self.changed,
                       "added": self.added, "missing": self.missing},
            "first": self.first.to_dict() if self.first else None,
            "by_unit_and_field": [{"unit": u, "field": f, "frames": n} for (u, f), n in self.groups.most_common()],
            "findings": {"golden": sum(self.findings_golden.values()),
                         "capture": sum(self.findings_capture.values()),
                         "added": self.findings_added, "gone": self.findings_gone},
            "rules_matching_no_field": self.unmatched,
        }


def _finding_short(line: str) -> str:
    """'finding warning eeprom_wear link=- unit=2' -> 'warning eeprom_wear u2'."""
    parts = line.split()[1:]
    keep = [p for p in parts if p not in ("link=-", "unit=-")]
    return " ".join(("u" + p[5:]) if p.startswith("unit=") else p for p in keep)


def _unit_label(c: Content) -> str:
    u = "-" if c.role in ("noise", "?") else f"u{c.unit}"
    return f"{c.link}:{u}" if c.link else u


class Collector:
    """Builds a CheckSummary from compare_lines' changed blocks (its on_change) and the findings lines."""

    def __init__(self, summary: CheckSummary, rules: FieldRules, names: Names, first=(1, 1)) -> None:
        self.s = summary
        self.rules = rules
        self.names = names
        self.first = first  # the file line numbers of frame 0 (golden, capture)

    def change(self, old: list[str], new: list[str], at_old: int, at_new: int) -> None:
        at_old, at_new = at_old - self.first[0] + 1, at_new - self.first[1] + 1
        po = [_line(x, self.names) for x in old]
        pn = [_line(x, self.names) for x in new]
        sm = difflib.SequenceMatcher(None, [c.key for _, _, c in po], [c.key for _, _, c in pn], autojunk=False)
        paired_o, paired_n = set(), set()
        for i, j, n in sm.get_matching_blocks():
            for k in range(n):
                paired_o.add(i + k)
                paired_n.add(j + k)
                self._changed(po[i + k], pn[j + k], at_new - 1 + j + k)
        if len(paired_o) < len(po) and len(paired_n) < len(pn) and not sm.get_matching_blocks()[:-1]:
            # nothing shares who it is: still a changed frame each, position by position
            for k in range(min(len(po), len(pn))):
                paired_o.add(k)
                paired_n.add(k)
                self._changed(po[k], pn[k], at_new - 1 + k)
        for k, (t, _, c) in enumerate(pn):
            if k not in paired_n:
                self.s.added += 1
                self.s.groups[(_unit_label(c), "(frame added)")] += 1
                self._first(at_new - 1 + k, t, c, "added", [])
        for k, (t, _, c) in enumerate(po):
            if k not in paired_o:
                self.s.missing += 1
                self.s.groups[(_unit_label(c), "(frame missing)")] += 1
                self._first(at_old - 1 + k, t, c, "missing", [])

    def _changed(self, old, new, frame: int) -> None:
        (t_a, l_a, a), (t_b, l_b, b) = old, new
        diffs = differences(a, b, self.rules)
        if not diffs:  # the content agrees (within the rules): the timing moved
            if t_a is not None and t_b is not None and t_a != t_b:
                diffs.append(("time", f"{t_a:.6f} s", f"{t_b:.6f} s"))
            if l_a != l_b:
                diffs.append(("latency", _ms(l_a), _ms(l_b)))
        if not diffs:
            return
        self.s.changed += 1
        for name, _, _ in diffs:
            self.s.groups[(_unit_label(b), name)] += 1
        self._first(frame, t_b, b, "changed", diffs)

    def _first(self, frame: int, t: float | None, c: Content, kind: str, diffs) -> None:
        if self.s.first is None:
            self.s.first = FirstDifference(frame, t, c.unit, c.fc, c.role, c.link, kind, diffs)


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f} ms"


def _line(line: str, names: Names) -> tuple[float | None, float | None, Content]:
    t, lat, content = split_line(line)
    return t, lat, parse(content, names)


def _headed(lines: Iterable[str]) -> tuple[int, Iterator[str]]:
    """(header lines, the stream after them): the hunks and frame numbers count from the first frame line."""
    it = iter(lines)
    n = 0
    for line in it:
        if not line.startswith("#"):
            return n, chain([line], it)
        n += 1
    return n, iter(())


def _frames(lines: Iterable[str], count: list[int], findings: Counter) -> Iterator[str]:
    """The frame lines of a golden stream (after its header), findings counted aside."""
    for line in lines:
        if line.startswith("#"):
            continue
        if line.startswith(FINDING):
            findings[line] += 1
            continue
        count[0] += 1
        yield line


def summarize(old: Iterable[str], new: Iterable[str], tol: Tolerances, names: tuple[str, str],
              point_names: Names | None = None) -> CheckSummary:
    """Compare a golden's lines (`old`) with a decode's (`new`), streaming: the summary and the unified diff."""
    point_names = point_names or Names()
    for n in tol.rules.exact_names():
        point_names.add(n)
    s = CheckSummary(*names)
    n_old, n_new = [0], [0]
    h_old, old = _headed(old)
    h_new, new = _headed(new)
    collect = Collector(s, tol.rules, point_names, (h_old + 1, h_new + 1))
    d = compare_lines(_frames(old, n_old, s.findings_golden), _frames(new, n_new, s.findings_capture), tol, names,
                      on_change=collect.change, point_names=point_names, start=(h_old + 1, h_new + 1))
    s.golden_frames, s.capture_frames = n_old[0], n_new[0]
    s.unmatched = tol.rules.unmatched(point_names.seen)
    s.known = point_names.seen
    gone, added = s.findings_gone, s.findings_added
    if gone or added:
        if not d:
            d = f"--- {names[0]}\n+++ {names[1]}\n"
        d += "".join(f"-{x}\n" for x in gone) + "".join(f"+{x}\n" for x in added)
    s.diff = d
    return s
