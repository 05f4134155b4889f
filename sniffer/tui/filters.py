"""The filter bar: its text <-> the store's Filter, in the filter language (sniffer.filterlang).

The keys u, f and e toggle a unit, a function and errors-only beside what the bar
says, so a bar filter is split: its plain top-level terms `link:a`, `u:1,2`, `fc:3`,
`role:req` and `err` become those fields, everything else stays text in the
language (`"Output frequency" > 50 lat>20ms ...`).  `filter_expr` joins them
again, so the bar reopens on the filter in force.
"""

from __future__ import annotations

from sniffer.filterlang import Query, conjuncts, parse
from sniffer.filterlang.nodes import And, Field, Flag, Links, Or, Roles
from sniffer.analysis.flags import F_PROBLEM

_FIELD = {"u": "units", "fc": "functions"}


def parse_filter(expr: str) -> dict:
    """Keyword arguments for FrameStore.update_filter; every field is set (the bar replaces the filter).
    FilterError (a ValueError naming the column) if the text does not parse."""
    kw: dict = {"units": None, "links": None, "functions": None, "roles": None, "errors_only": False, "text": ""}
    rest = []
    for term in conjuncts(parse(expr)):
        name = _FIELD.get(term.key) if isinstance(term, Field) else None
        if name and kw[name] is None and term.points is not None:
            kw[name] = frozenset(int(v) for v in term.points)
        elif isinstance(term, Links) and kw["links"] is None:
            kw["links"] = term.names
        elif isinstance(term, Roles) and kw["roles"] is None:
            kw["roles"] = term.names
        elif isinstance(term, Flag) and term.mask == F_PROBLEM:
            kw["errors_only"] = True
        else:
            rest.append(term)
    kw["text"] = str(And(tuple(rest)) if len(rest) > 1 else rest[0]) if rest else ""
    return kw


def filter_expr(flt) -> str:
    """The bar's text for a Filter (parse_filter's inverse), so the bar opens on the current filter."""
    parts = []
    if flt.links is not None:
        parts.append("link:" + ",".join(sorted(flt.links)))
    if flt.units is not None:
        parts.append("u:" + ",".join(map(str, sorted(flt.units))))
    if flt.functions is not None:
        parts.append("fc:" + ",".join(map(str, sorted(flt.functions))))
    if flt.roles is not None:
        parts.append("role:" + ",".join(sorted(flt.roles)))
    if flt.errors_only:
        parts.append("err")
    if flt.text:
        parts.append(f"({flt.text})" if parts and isinstance(parse(flt.text), Or) else flt.text)
    return " ".join(parts)


def filter_query(flt) -> Query:
    """The Filter as one query: its fields and its text and-ed."""
    return Query(filter_expr(flt))
