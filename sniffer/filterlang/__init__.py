"""The filter language: which frames to show (the TUI's '/' bar) or to trigger on.

    from sniffer.filterlang import Query, Context
    q = Query('u:1 "Output frequency" > 50 or lat>20ms')
    q.matches(frame, Context(t0_ns))       # one frame (a trigger)
    q.rows(store, len(store))              # the passing rows of a store, columns first (the TUI)
    str(q)                                  # the filter's canonical text

Grammar (words and keys are case-insensitive; a filter of nothing passes every frame):

    filter   := or
    or       := and ( ("or" | "||" | "|") and )*
    and      := unary ( ["and" | "&&" | "&"] unary )*       two terms side by side: and
    unary    := ("not" | "!") unary | "(" or ")" | term
    term     := key ":" items                                u:1,2  reg:2520H..2525H  link:drives
              | operand op value                             "Output frequency" > 50   lat>20ms
              | flag                                         err crc exc timeout fault noise warn
              | "rate" "(" or ")" op count "/" time          rate(crc) > 5/min   (no rate inside)
              | word | "quoted text"                         free text
    items    := item ("," item)*       item := value | [value] ".." [value]   (ranges include both ends)
    op       := ">" | ">=" | "<" | "<=" | "=" | "==" | "!=" | "~"    (~: the text contains)
    operand  := field | point
    field    := u | fc | t | lat                              (also unit, function, time, latency)
    point    := a decoded point's name or parameter id, quoted when it has spaces ("Output frequency",
                Un-01), or a register: holding[300], 2524H, 0x12C, 300

Keys: `u:` unit numbers; `fc:` function codes (3, 16, 0x10; an exception response counts as its
function); `role:` req, rsp, noise, unknown; `reg:` registers a frame touches (reads, writes,
its response's values): 9508 decimal, 2520H or 0x2520 hex, holding[300] / input[5] / coil[3] /
discrete[0] for one table, a model's parameter id (12-00, Cn-02), ranges 2520H..2525H; `t:` time since
the capture started, a range only (t:10s..20s, t:..5s, t:30s..; units ns us ms s min h, bare numbers
in s); `lat:` the response's latency, a range (bare numbers in ms); `model:` the decoder (a510,
tds-v8, generic); `link:` the link, in a capture of several links (`sniffer live P1 P2`, --tap,
a bus file's [[links]]): link:drives,pumps (a unit is its link's: `link:drives u:1`).
Fields compare too: lat>20ms, t>=5s, u!=9, fc=16.

Rates: `rate(EXPR) > 5/min` is the count of frames matching EXPR in the last minute of capture time
(rate(timeout u:3) >= 3/10s, rate(exc) < 1/h); see sniffer/filterlang/rate.py.  A query with a rate
keeps the recent matching times: give it every frame in order (a trigger), or a store's rows.

Flags: `err` any problem (as the `e` key), `crc` a bad CRC / LRC, `exc` an exception response,
`timeout` a request without a (timely) response, `fault` a drive fault or alarm, `noise`, `warn`.

Points: a frame passes when one of its decoded points passes: a number against the scaled value
(a unit written after it must be the point's: > 50Hz), text against the point's text, its mnemonic
(the A510 fault "OV — Over voltage" = OV) or value; `!=` needs the point and no equal value.

Free text: a word (or a quoted phrase, which is never a key, flag or register) is searched in the
summary, every decoded point's name, parameter id, unit and text, annotation codes and details,
exception names, the model, the noise reason and the raw bytes in hex; a role name matches that
role; a word that reads as a register (300, 012CH, 0x12c, holding[300]) or a parameter id (12-00)
also finds the frames touching that register.

Errors: `FilterError` (a ValueError), one line with the column: "filter error at column 7: '>'
needs a value after it".

A frame without a field never passes a test of it (noise has no unit, a request no latency), so
`lat>20ms` lists responses and `!lat>20ms` everything else.
"""

from __future__ import annotations

from sniffer.filterlang.facts import (
    Context, Facts, matches_text, register_cell, register_ids, registers_of, search_text,
)
from sniffer.filterlang.nodes import Node
from sniffer.filterlang.parser import FLAGS, KEYS, ROLES, FilterError, conjuncts, parse
from sniffer.filterlang.rate import SlidingCount, rate_terms


class Query:
    """A parsed filter, evaluated on a frame or on a store's columns (nodes.py says what `cols` holds).

    A filter with `rate(...)` terms keeps each one's recent matching times, so `matches` is called on
    every frame in order (one Query per stream)."""

    def __init__(self, source: str | Node | None) -> None:
        self.node = parse(source) if isinstance(source, str) else source
        self.rates = rate_terms(self.node)
        self._counts = {r: SlidingCount(r.window_ns) for r in self.rates}

    def __str__(self) -> str:
        return "" if self.node is None else str(self.node)

    def __bool__(self) -> bool:
        return self.node is not None

    def matches(self, frame, ctx=None, flags: int | None = None, regs: list | None = None) -> bool:
        """Does one frame pass?  `ctx` a Context (capture start, parameter ids); flags and registers
        when the caller has them already."""
        if self.node is None:
            return True
        fx = Facts(frame, ctx or Context(), flags, regs)
        if self.rates:
            fx.rates = self._observe(fx)
        return self.node.test(fx)

    def _observe(self, fx: Facts) -> dict:
        """Count this frame into every rate it matches; what each rate says at its time."""
        out = {}
        t = fx.frame.t_ns
        for r in self.rates:
            w = self._counts[r]
            if r.item.test(fx):
                w.add(t)
            out[r] = r.passes(w.count(t))
        return out

    def rows(self, cols, end: int) -> list[int]:
        """The rows 0..end-1 of a store that pass, ascending: answered from its columns and search
        text, and from the frames (`cols.peek(row)`) only where those cannot decide."""
        if self.node is None:
            return list(range(end))
        sure, maybe = self.node.rows(cols, range(end))
        passing = {r: r.rows(cols, range(end))[0] for r in self.rates} if maybe and self.rates else {}
        if maybe:
            node, flags = self.node, cols.flags
            for row in sorted(maybe):
                fx = Facts(cols.peek(row), cols, flags[row])
                if passing:
                    fx.rates = {r: row in rows for r, rows in passing.items()}
                if node.test(fx):
                    sure.add(row)
        for r in self.rates:  # frames that come after these rows are counted on from them
            self._counts[r].seed(r.match_times(cols, end))
        return sorted(sure)


def point_names(node: Node | None) -> list[str]:
    """The names of the points a filter compares (lower case), in order."""
    from sniffer.filterlang.nodes import Compare

    if node is None:
        return []
    if isinstance(node, Compare):
        return [node.name] if node.name else []
    out = []
    for child in (*getattr(node, "items", ()), getattr(node, "item", None)):
        if isinstance(child, Node):
            out += point_names(child)
    return out


def keyword_typos(node: Node | None) -> list[str]:
    """A note for each point name that is a field or flag mistyped ('unti == 1' compares a point named unti,
    which no frame has: it never matches, and says nothing)."""
    import difflib

    words = sorted({*KEYS, *FLAGS})
    out = []
    for name in dict.fromkeys(point_names(node)):
        close = difflib.get_close_matches(name, words, n=1, cutoff=0.75)
        if close and name not in words:
            out.append(f"{name!r} is read as a point's name; did you mean the field {close[0]!r}?")
    return out


__all__ = ["FLAGS", "KEYS", "ROLES", "Context", "Facts", "FilterError", "Query", "conjuncts", "keyword_typos",
           "matches_text", "parse", "point_names", "register_cell", "register_ids", "registers_of", "search_text"]
