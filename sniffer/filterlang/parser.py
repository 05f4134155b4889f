"""Text -> tree of terms (nodes.py): a tokenizer and a recursive-descent parser.

Precedence, loosest first: `or` (also `||`, `|`), `and` (also `&&`, `&`, or nothing between two
terms), `not` (also `!`); parentheses group.  Every error is one FilterError with the column.
Parentheses and `not`s nest at most MAX_DEPTH deep (the parser and the tree it builds recurse).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from sniffer.analysis.flags import F_CRC, F_EXC, F_FAULT, F_NOISE, F_PROBLEM, F_TIMEOUT, F_WARN
from sniffer.filterlang.nodes import And, Compare, Field, Flag, Links, Models, Node, Not, Or, Regs, Roles, Text
from sniffer.filterlang.rate import make_rate
from sniffer.filterlang.values import (
    BadValue, Interval, RegRange, comparison_intervals, looks_like_register, parse_duration, parse_int, parse_number,
    parse_register, split_range,
)


class FilterError(ValueError):
    """A filter that does not parse: `pos` is the 0-based offset of the trouble."""

    def __init__(self, msg: str, pos: int) -> None:
        super().__init__(f"filter error at column {pos + 1}: {msg}")
        self.msg = msg
        self.pos = pos


KEYS = {"u": "u", "unit": "u", "fc": "fc", "function": "fc", "role": "role", "reg": "reg", "register": "reg",
        "t": "t", "time": "t", "lat": "lat", "latency": "lat", "model": "model",
        "link": "link"}
FIELDS = {k: v for k, v in KEYS.items() if v in ("u", "fc", "t", "lat")}  # these compare: lat>20ms
FLAGS = {"err": F_PROBLEM, "errors": F_PROBLEM, "error": F_PROBLEM, "crc": F_CRC, "exc": F_EXC,
         "exception": F_EXC, "exceptions": F_EXC, "timeout": F_TIMEOUT, "timeouts": F_TIMEOUT, "fault": F_FAULT,
         "faults": F_FAULT, "noise": F_NOISE, "warn": F_WARN, "warning": F_WARN, "warnings": F_WARN}
ROLES = {"req": "request", "request": "request", "rsp": "response", "resp": "response", "response": "response",
         "noise": "noise", "unknown": "unknown", "?": "unknown"}
_TIME_DEFAULT = {"t": "s", "lat": "ms"}  # a bare number's unit
_ID = re.compile(r"[a-z]*\d*-\d+\Z", re.I)  # a parameter id as the manuals write them: 12-00, Cn-02
_SPECIAL = frozenset("()\"'<>=!~&|")
_OPS = (">=", "<=", "==", "!=", ">", "<", "=", "~")
MAX_DEPTH = 100  # parentheses and nots inside each other: no filter a person writes comes near it


@dataclass(frozen=True)
class Tok:
    kind: str  # WORD STR OP LP RP NOT AND OR
    text: str  # as typed
    value: str  # a string's text without its quotes
    pos: int
    end: int
    space: bool  # whitespace before it


def tokenize(s: str) -> list[Tok]:
    toks: list[Tok] = []
    i, n, space = 0, len(s), True
    while i < n:
        c = s[i]
        if c.isspace():
            i += 1
            space = True
            continue
        start, value = i, ""
        if c in "()":
            kind = "LP" if c == "(" else "RP"
            i += 1
        elif c in "\"'":
            j, buf = i + 1, []
            while j < n and s[j] != c:
                if s[j] == "\\" and j + 1 < n:
                    j += 1
                buf.append(s[j])
                j += 1
            if j >= n:
                raise FilterError(f"the quote {c} is not closed", i)
            kind, value, i = "STR", "".join(buf), j + 1
        elif c == "!" and s[i + 1:i + 2] != "=":
            kind = "NOT"
            i += 1
        elif c in "&|":
            kind = "AND" if c == "&" else "OR"
            i += 2 if s[i + 1:i + 2] == c else 1
        elif c in "<>=!~":
            op = next(o for o in _OPS if s.startswith(o, i))
            kind = "OP"
            i += len(op)
        else:
            while i < n and not s[i].isspace() and s[i] not in _SPECIAL:
                i += 1
            kind = "WORD"
        toks.append(Tok(kind, s[start:i], value, start, i, space))
        space = False
    return toks


def parse(text: str) -> Node | None:
    """The tree of a filter, or None for an empty one; FilterError (with the column) if it does not parse."""
    return _Parser(text).run()


def _is(t: Tok | None, kind: str, word: str) -> bool:
    return t is not None and (t.kind == kind or (t.kind == "WORD" and t.text.lower() == word))


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.toks = tokenize(text)
        self.i = 0
        self.in_rate = False
        self.depth = 0

    @property
    def peek(self) -> Tok | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def next(self) -> Tok | None:
        t = self.peek
        self.i += 1
        return t

    def fail(self, msg: str, pos: int):
        raise FilterError(msg, pos)

    def run(self) -> Node | None:
        if not self.toks:
            return None
        node = self.or_()
        t = self.peek
        if t is not None:
            self.fail("')' without its '('" if t.kind == "RP" else f"unexpected {t.text!r}", t.pos)
        return node

    def or_(self) -> Node:
        items = [self.and_()]
        while _is(self.peek, "OR", "or"):
            items.append(self.and_(after=self.next()))
        return items[0] if len(items) == 1 else Or(tuple(_flat(items, Or)))

    def and_(self, after: Tok | None = None) -> Node:
        items = [self.unary(after)]
        while (t := self.peek) is not None and t.kind != "RP" and not _is(t, "OR", "or"):
            if _is(t, "AND", "and"):
                self.next()
                items.append(self.unary(after=t))
            else:
                items.append(self.unary())
        return items[0] if len(items) == 1 else And(tuple(_flat(items, And)))

    def deeper(self, t: Tok) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            self.fail(f"parentheses and nots nested more than {MAX_DEPTH} deep", t.pos)

    def unary(self, after: Tok | None = None) -> Node:
        t = self.peek
        if t is None:
            where = len(self.text)
            self.fail(f"{after.text!r} needs a term after it" if after else "a term is missing", where)
        if _is(t, "NOT", "not"):
            self.next()
            self.deeper(t)
            node = Not(self.unary(after=t))
            self.depth -= 1
            return node
        if after is not None and (t.kind == "RP" or _is(t, "OR", "or") or _is(t, "AND", "and")):
            self.fail(f"{after.text!r} needs a term after it", t.pos)
        return self.primary()

    def primary(self) -> Node:
        t = self.next()
        if t.kind == "LP":
            if self.peek is not None and self.peek.kind == "RP":
                self.fail("empty parentheses", t.pos)
            self.deeper(t)
            node = self.or_()
            self.depth -= 1
            close = self.next()
            if close is None or close.kind != "RP":
                where = len(self.text) if close is None else close.pos
                self.fail(f"the '(' at column {t.pos + 1} is not closed", where)
            return node
        if t.kind == "RP":
            self.fail("')' without its '('", t.pos)
        if t.kind == "OP":
            self.fail(f"{t.text!r} needs a point name or a field (u, fc, t, lat) before it", t.pos)
        if t.kind in ("AND", "OR") or t.text.lower() in ("and", "or"):
            self.fail(f"{t.text!r} needs a term before it", t.pos)
        if t.kind == "WORD" and t.text.lower() == "rate" and self.peek is not None and self.peek.kind == "LP":
            return self.rate(t)
        key, sep, rest = t.text.partition(":") if t.kind == "WORD" else ("", "", "")
        k = key.lower()
        if sep and k in KEYS:
            return self.keyed(t, KEYS[k], key, rest)
        if sep and k.isalpha():
            self.fail(f"unknown key {key + ':'!r} (u: fc: role: reg: t: lat: model: link:); quote text to search it",
                      t.pos)
        if self.peek is not None and self.peek.kind == "OP":
            return self.compare(t, self.next())
        if t.kind == "STR":
            if not t.value:
                self.fail("empty quotes", t.pos)
            return Text(t.text, t.value.lower())
        low = t.text.lower()
        if low in FLAGS:
            return Flag(t.text, FLAGS[low])
        return Text(t.text, low, self._word_registers(t.text))

    @staticmethod
    def _word_registers(word: str) -> Regs | None:
        """A free word that reads as a register (300, 012CH, holding[300]) or a parameter id (12-00) also
        finds the frames touching that register."""
        if looks_like_register(word):
            table, a = parse_register(word)
            return Regs(word, (RegRange(table, a, a),), point_ids=False)
        if _ID.match(word):
            return Regs(word, (), (word.lower(),), point_ids=False)
        return None

    # ------------------------------------------------------------ key:value
    def keyed(self, t: Tok, key: str, typed: str, rest: str) -> Node:
        src, at = t.text, t.pos + len(typed) + 1
        if not rest:
            s = self.peek
            if s is None or s.kind != "STR" or s.space:
                self.fail(f"{typed + ':'!r} needs a value", t.end)
            self.next()
            src, rest, at = t.text + s.text, s.value, s.pos + 1
        items = []
        off = 0
        for part in rest.split(","):
            if part:
                items.append((part, at + off))
            off += len(part) + 1
        if not items:
            self.fail(f"{typed + ':'!r} needs a value", at)
        if key == "role":
            return Roles(src, frozenset(self._role(p, pos) for p, pos in items))
        if key == "model":
            return Models(src, frozenset(p.lower() for p, _ in items))
        if key == "link":
            return Links(src, frozenset(p.lower() for p, _ in items))
        if key == "reg":
            ranges, ids = [], []
            for p, pos in items:
                got = self._register_item(p, pos)
                (ids if isinstance(got, str) else ranges).append(got)
            return Regs(src, tuple(ranges), tuple(ids))
        return Field(src, key, tuple(self._interval(key, p, pos) for p, pos in items))

    def _role(self, p: str, pos: int) -> str:
        r = ROLES.get(p.lower())
        if r is None:
            self.fail(f"unknown role {p!r} (req, rsp, noise, unknown)", pos)
        return r

    def _interval(self, key: str, p: str, pos: int) -> Interval:
        ends = split_range(p)
        if ends is None:
            if key in _TIME_DEFAULT:
                self.fail(f"{key}: takes a range ({key}:10..20, {key}:..5, {key}:30..) or compare: {key}>{p}", pos)
            v = self._number(key, p, pos)
            return Interval(v, v)
        lo, hi = ends
        return Interval(None if not lo else self._number(key, lo, pos),
                        None if not hi else self._number(key, hi, pos + len(lo) + 2))

    def _number(self, key: str, p: str, pos: int) -> float:
        try:
            if key in _TIME_DEFAULT:
                v = parse_duration(p, _TIME_DEFAULT[key])
                return v if key == "t" else v / 1000  # lat in microseconds
        except BadValue as e:
            self.fail(str(e), pos + e.offset)
        v = parse_int(p)
        if v is None or not 0 <= v <= 255:
            self.fail(f"{'a unit' if key == 'u' else 'a function code'} is 0..255, not {p!r}", pos)
        return v

    def _register_item(self, p: str, pos: int) -> RegRange | str:
        ends = split_range(p)
        if ends is None:
            reg = self._register(p, pos)
            if reg is not None:
                return RegRange(reg[0], reg[1], reg[1])
            if not any(c.isdigit() for c in p):
                self.fail(f"not a register: {p!r} (300, 012CH, 0x12C, holding[300], a parameter id like 12-00)",
                          pos)
            return p.lower()
        lo_s, hi_s = ends
        lo = self._register(lo_s, pos) if lo_s else (None, 0)
        hi = self._register(hi_s, pos + len(lo_s) + 2) if hi_s else (None, 0x1FFFF)
        if lo is None or hi is None:
            self.fail(f"a register range takes register numbers: {p!r}", pos)
        if lo[0] and hi[0] and lo[0] != hi[0]:
            self.fail(f"a range within one table: {p!r}", pos)
        return RegRange(lo[0] or hi[0], lo[1], hi[1])

    def _register(self, p: str, pos: int):
        try:
            return parse_register(p)
        except BadValue as e:
            self.fail(str(e), pos + e.offset)

    # ------------------------------------------------------------ rate(EXPR) > 5/min
    def rate(self, t: Tok) -> Node:
        """rate "(" or ")" op N/TIME (filterlang.rate)."""
        if self.in_rate:
            self.fail("a rate inside a rate", t.pos)
        lp = self.next()
        if self.peek is not None and self.peek.kind == "RP":
            self.fail("rate() needs a filter inside: rate(crc)", lp.pos)
        self.in_rate = True
        self.deeper(lp)
        item = self.or_()
        self.depth -= 1
        self.in_rate = False
        close = self.next()
        if close is None or close.kind != "RP":
            self.fail(f"the '(' at column {lp.pos + 1} is not closed", len(self.text) if close is None else close.pos)
        op = self.next()
        if op is None or op.kind != "OP" or op.text == "~":
            self.fail("rate(...) compares with a count per time: rate(crc) > 5/min",
                      len(self.text) if op is None else op.pos)
        value = self.peek
        if value is None or value.kind != "WORD":
            self.fail(f"{op.text!r} needs a count per time after it: 5/min", op.end if value is None else value.pos)
        self.next()
        try:
            return make_rate(self.text[t.pos:value.end], item, op.text, value.text)
        except BadValue as e:
            self.fail(str(e), value.pos + e.offset)

    # ------------------------------------------------------------ comparisons
    def compare(self, lhs: Tok, op: Tok) -> Node:
        rhs = self.peek
        if rhs is None or rhs.kind not in ("WORD", "STR"):
            self.fail(f"{op.text!r} needs a value after it", op.end if rhs is None else rhs.pos)
        self.next()
        src = lhs.text + (" " if op.space else "") + op.text + (" " if rhs.space else "") + rhs.text
        value = rhs.value if rhs.kind == "STR" else rhs.text
        key = FIELDS.get(lhs.text.lower()) if lhs.kind == "WORD" else None
        if key is not None:
            if op.text == "~":
                self.fail(f"'~' compares text; {lhs.text} is a number", op.pos)
            v = self._number(key, value, rhs.pos + (rhs.kind == "STR"))
            return Field(src, key, comparison_intervals(op.text, v))
        name, table, address = self._point(lhs)
        number, unit = None, ""
        got = parse_number(value) if op.text != "~" else None
        if got is not None:
            number, unit = got[0], got[1].lower()
        elif op.text in ("<", ">", "<=", ">="):
            self.fail(f"{op.text!r} compares numbers; {value!r} is not one", rhs.pos)
        spans = comparison_intervals(op.text, number) if number is not None else ()
        return Compare(src, name, table, address, op.text, number, unit, value.lower(), spans)

    def _point(self, lhs: Tok) -> tuple[str | None, str | None, int | None]:
        """(name, table, address) of a comparison's point: a register (holding[300]; bare: 300, 012CH), or
        a name / parameter id."""
        quoted = lhs.kind == "STR"
        typed = lhs.value if quoted else lhs.text
        reg = self._register(typed, lhs.pos + quoted)
        if reg is not None and (not quoted or reg[0] is not None):
            return None, reg[0], reg[1]
        if not typed:
            self.fail("empty quotes", lhs.pos)
        return typed.lower(), None, None


def _flat(items: list[Node], kind: type) -> list[Node]:
    """a (b c) is a b c: an And's parenthesised And joins it (an Or's Or likewise)."""
    out: list[Node] = []
    for i in items:
        out.extend(i.items if isinstance(i, kind) else (i,))
    return out


def conjuncts(node: Node | None) -> list[Node]:
    """The terms and-ed at the top of a filter (one, if it is not an And)."""
    if node is None:
        return []
    return list(node.items) if isinstance(node, And) else [node]


__all__ = ["FIELDS", "FLAGS", "FilterError", "KEYS", "ROLES", "Tok", "conjuncts", "parse", "tokenize"]
