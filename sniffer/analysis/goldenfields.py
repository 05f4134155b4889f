"""A golden line's content as named fields, and the field rules `check` compares them with.

A golden line's content is `role uN model fcXX crc=.. pair=.. summary [| rest: ...] [codes]`; the summary
is `name=value[ unit][ [text]]` point after point, and names hold spaces, commas and brackets
("Fault cause, low word (cleared by fault reset)", "holding[8192]").  Where one point's value ends and the
next name begins cannot be read from the text alone, so the split is anchored on names known to be point
names: the capture's own (the decode that made the new line saw them) and the names the rules give.
Without them a name is one word before '='.

`FieldRules` are the user's `--ignore FIELD` (a name or a glob) and `--tolerance 'FIELD=0.2A'` (absolute,
in the field's unit) or `'FIELD=5%'` (relative to the golden's value); they are kept in the golden's header
(`options_line`) so the next run uses them.
"""

from __future__ import annotations

import fnmatch
import re
from collections.abc import Iterable
from dataclasses import dataclass, field

_HEAD = re.compile(r"^(?:link=(?P<link>\S+) )?(?P<role>\S+) u(?P<unit>\S+) (?P<model>\S+) fc(?P<fc>\S+) "
                   r"crc=(?P<crc>\S+) pair=(?P<pair>\S+) ?(?P<summary>.*)$")
_NOISE = re.compile(r"^(?:link=(?P<link>\S+) )?NOISE (?P<summary>.*)$")
_CODES = re.compile(r" \[(?P<codes>[a-z0-9_]+(?:\.[a-z0-9_]+)+(?:,[a-z0-9_]+(?:\.[a-z0-9_]+)+)*)\]$")
_MORE = re.compile(r" \.\.\. \(\+\d+\)(?: \| rest:)?")
_WORD_NAME = re.compile(r"(?:^| )([^\s=\[\]]+(?:\[\d+\])?)=")
_NUMBER = re.compile(r"^(?P<n>[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)(?: (?P<unit>[^\s\[]+))?")
_TOL = re.compile(r"^(?P<n>\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)\s*(?P<unit>\S*)$")
HEAD_FIELDS = ("role", "model", "crc", "pair")
LINE_FIELDS = frozenset({*HEAD_FIELDS, "codes", "noise"})  # a golden line's fields besides its points


@dataclass(frozen=True)
class Content:
    """One golden line's content: who (link, role, unit, function) and its fields in order."""

    link: str
    role: str
    unit: str
    fc: str
    fields: dict[str, str]

    @property
    def key(self) -> tuple[str, str, str, str]:
        return self.link, self.role, self.unit, self.fc


class Names:
    """Point names seen in the capture: the anchors a summary is split on (one regex, rebuilt as it grows)."""

    def __init__(self, names: Iterable[str] = ()) -> None:
        self.names: set[str] = set(names)
        self.seen: set[str] = set(names)  # the names frames had (not those added as anchors only)
        self._rx: re.Pattern | None = None
        self._n = -1

    def add(self, name: str) -> None:
        self.names.add(name)

    def add_seen(self, names: Iterable[str]) -> None:
        """Names the frames of a part had (check by parts)."""
        names = set(names)
        self.names |= names
        self.seen |= names

    def add_frame(self, f) -> None:
        pts = f._points
        if not pts:
            return
        samples = getattr(pts, "samples", None)  # a register block: its names without building the dicts
        for p in (samples() if samples else pts):
            name = p[0] if samples else p["name"]
            self.names.add(name)
            self.seen.add(name)

    def regex(self) -> re.Pattern | None:
        if self._n != len(self.names):
            self._n = len(self.names)
            alts = "|".join(re.escape(n) for n in sorted(self.names, key=len, reverse=True) if n)
            self._rx = re.compile(rf"(?:^| )({alts})=") if alts else None
        return self._rx


def _depths(text: str) -> list[int]:
    """The bracket depth at each position (a point's [text] holds '=' that are no anchors)."""
    out, d = [], 0
    for ch in text:
        if ch == "]":
            d = max(0, d - 1)
        out.append(d)
        if ch == "[":
            d += 1
    return out


def _points(summary: str, names: Names | None) -> dict[str, str]:
    rx = names.regex() if names is not None else None
    depth = _depths(summary)
    anchors: dict[int, tuple[int, str]] = {}  # name start -> (value start, name)
    for pattern in (rx, _WORD_NAME):
        if pattern is None:
            continue
        for m in pattern.finditer(summary):
            s = m.start(1)
            if depth[s] == 0 and not any(a <= s < v for a, (v, _) in anchors.items()):
                anchors.setdefault(s, (m.end(), m.group(1)))
        if anchors and pattern is rx:
            break  # the capture's names split it: single words inside their values are no names
    out: dict[str, str] = {}
    starts = sorted(anchors)
    if not starts or starts[0] > 0:
        out["summary"] = summary[:starts[0] if starts else len(summary)].strip()
    for i, s in enumerate(starts):
        v, name = anchors[s]
        end = starts[i + 1] if i + 1 < len(starts) else len(summary)
        key, n = name, 2
        while key in out:  # a name twice in one frame (a repeated register): the second is name#2
            key, n = f"{name}#{n}", n + 1
        out[key] = summary[v:end].strip()
    return out


def parse(content: str, names: Names | None = None) -> Content:
    """The fields of a golden line's content (the part after ' | ')."""
    codes = ""
    m = _CODES.search(content)
    if m:
        codes, content = m.group("codes"), content[:m.start()]
    h = _HEAD.match(content)
    if h is None:
        n = _NOISE.match(content)
        link = (n.group("link") if n else None) or ""
        fields = {"noise": n.group("summary") if n else content}
        role = unit = fc = "-"
        role = "noise" if n else "?"
    else:
        link, role, unit, fc = h.group("link") or "", h.group("role"), h.group("unit"), h.group("fc")
        fields = {k: h.group(k) for k in HEAD_FIELDS if k != "role"}
        fields.update(_points(_MORE.sub("", h.group("summary")), names))
    fields["codes"] = codes
    return Content(link, role, unit, fc, fields)


def number(value: str) -> tuple[float, str] | None:
    """(number, unit) of a value such as '11.5 A' or '25 [Run=Running]'; None if it is no number."""
    m = _NUMBER.match(value)
    return (float(m.group("n")), m.group("unit") or "") if m else None


@dataclass(frozen=True)
class Tolerance:
    amount: float
    unit: str = ""  # absolute in this unit ('' = the field's own); '%' = relative to the golden value

    def allows(self, old: str, new: str) -> bool:
        a, b = number(old), number(new)
        if a is None or b is None:
            return False
        if self.unit == "%":
            return a[1] == b[1] and abs(a[0] - b[0]) <= abs(a[0]) * self.amount / 100 + 1e-12
        if self.unit and (a[1] != self.unit or b[1] != self.unit):
            return False  # a tolerance in A says nothing about a value in V
        return a[1] == b[1] and abs(a[0] - b[0]) <= self.amount + 1e-9

    def text(self) -> str:
        return f"{self.amount:g}{self.unit}"


def parse_tolerance(text: str) -> tuple[str, Tolerance]:
    """'Output current=0.2A' / 'Output current=5%' -> (name, Tolerance); ValueError with the reason."""
    name, sep, amount = text.rpartition("=")
    m = _TOL.match(amount.strip())
    if not sep or not name.strip() or m is None:
        raise ValueError(f"--tolerance {text!r}: expected FIELD=AMOUNT, as 'Output current=0.2A' or "
                         "'Output current=5%'")
    return name.strip(), Tolerance(float(m.group("n")), m.group("unit"))


def matches(name: str, pattern: str) -> bool:
    """A field name against a rule: the name itself, or a glob of * and ? (brackets are literal: register names
    such as 'holding[8451]' carry them)."""
    return name == pattern or fnmatch.fnmatchcase(name, pattern.replace("[", "[[]"))


@dataclass(frozen=True)
class FieldRules:
    """Fields a comparison leaves out (`ignore`, names or globs) or compares within a tolerance."""

    ignore: tuple[str, ...] = ()
    tolerance: tuple[tuple[str, Tolerance], ...] = field(default=())

    def __bool__(self) -> bool:
        return bool(self.ignore or self.tolerance)

    def ignored(self, name: str) -> bool:
        base = name.split("#", 1)[0]
        return any(matches(base, g) for g in self.ignore)

    def tolerance_of(self, name: str) -> Tolerance | None:
        base = name.split("#", 1)[0]
        for pattern, tol in self.tolerance:
            if matches(base, pattern):
                return tol
        return None

    def patterns(self) -> list[str]:
        return [*self.ignore, *(p for p, _ in self.tolerance)]

    def exact_names(self) -> list[str]:
        return [n for n in self.patterns() if not any(c in n for c in "*?")]

    def unmatched(self, names: Iterable[str]) -> list[str]:
        """The rules that match none of `names` (the fields the capture has): a mistyped name ignores nothing."""
        bases = {n.split("#", 1)[0] for n in names} | LINE_FIELDS
        return [p for p in self.patterns() if not any(matches(b, p) for b in bases)]

    def merged(self, other: FieldRules) -> FieldRules:
        """These rules with `other`'s added (other's tolerance wins for the same field)."""
        ignore = tuple(dict.fromkeys((*self.ignore, *other.ignore)))
        tol = dict(self.tolerance)
        tol.update(other.tolerance)
        return FieldRules(ignore, tuple(tol.items()))

    def to_json(self) -> dict:
        out: dict = {}
        if self.ignore:
            out["ignore"] = list(self.ignore)
        if self.tolerance:
            out["tolerance"] = {n: t.text() for n, t in self.tolerance}
        return out

    @classmethod
    def from_json(cls, d: dict) -> FieldRules:
        tol = tuple(parse_tolerance(f"{n}={t}") for n, t in (d.get("tolerance") or {}).items())
        return cls(tuple(str(x) for x in d.get("ignore") or ()), tol)


NO_RULES = FieldRules()


def differences(old: Content, new: Content, rules: FieldRules = NO_RULES) -> list[tuple[str, str, str]]:
    """(field, old value, new value) of each field that differs beyond the rules ('' = absent)."""
    out = []
    for name in dict.fromkeys((*old.fields, *new.fields)):
        a, b = old.fields.get(name, ""), new.fields.get(name, "")
        if a == b or rules.ignored(name):
            continue
        tol = rules.tolerance_of(name)
        if tol is not None and tol.allows(a, b):
            continue
        out.append((name, a, b))
    if old.role != new.role:
        out.insert(0, ("role", old.role, new.role))
    if (old.link, old.unit, old.fc) != (new.link, new.unit, new.fc):
        out.insert(0, ("frame", f"{old.link} u{old.unit} fc{old.fc}", f"{new.link} u{new.unit} fc{new.fc}"))
    return out
