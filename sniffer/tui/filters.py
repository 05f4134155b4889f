"""The filter bar's little language: `u:1,2 fc:3,16 role:req err words...`."""

from __future__ import annotations

_ROLE = {"req": "request", "request": "request", "rsp": "response", "resp": "response",
         "response": "response", "noise": "noise", "unknown": "unknown", "?": "unknown"}


def _ints(s: str, base: int) -> frozenset[int]:
    try:
        return frozenset(int(x.lstrip("0") or "0", base) if base == 0 and not x.lower().startswith("0x")
                         else int(x, base) for x in s.split(",") if x)
    except ValueError:
        raise ValueError(f"not a number list: {s!r}") from None


def parse_filter(expr: str) -> dict:
    """Keyword arguments for FrameStore.update_filter; every field is set (the bar replaces the filter)."""
    kw: dict = {"units": None, "functions": None, "roles": None, "errors_only": False, "text": ""}
    words = []
    for tok in expr.split():
        key, sep, val = tok.partition(":")
        k = key.lower()
        if sep and k in ("u", "unit"):
            kw["units"] = _ints(val, 10)
        elif sep and k in ("fc", "function"):
            kw["functions"] = _ints(val, 0)  # decimal, or 0x10
        elif sep and k == "role":
            try:
                kw["roles"] = frozenset(_ROLE[r.lower()] for r in val.split(",") if r)
            except KeyError as e:
                raise ValueError(f"unknown role {e.args[0]!r} (req, rsp, noise, unknown)") from None
        elif tok.lower() in ("err", "errors"):
            kw["errors_only"] = True
        else:
            words.append(tok)
    kw["text"] = " ".join(words)
    return kw


def filter_expr(flt) -> str:
    """The bar's text for a Filter (parse_filter's inverse), so the bar opens on the current filter."""
    parts = []
    if flt.units is not None:
        parts.append("u:" + ",".join(map(str, sorted(flt.units))))
    if flt.functions is not None:
        parts.append("fc:" + ",".join(map(str, sorted(flt.functions))))
    if flt.roles is not None:
        parts.append("role:" + ",".join(sorted(flt.roles)))
    if flt.errors_only:
        parts.append("err")
    if flt.text:
        parts.append(flt.text)
    return " ".join(parts)
