"""A RegisterMap as the TOML file docs/register-map-format.md describes (`load_map` reads it back equal).

One register per row (a row's `count` is expanded already in the map), the fields that differ
from their defaults, then [model], [exceptions], [enums.*], [bits.*].
"""

from __future__ import annotations

import math
from dataclasses import fields

from ..tables import Register, RegisterMap

_DEFAULTS = {f.name: f.default for f in fields(Register)}
_ALWAYS = ("addr", "id", "name", "type", "access")  # written even when they are the default


def _string(s: str) -> str:
    out = ['"']
    for ch in s:
        o = ord(ch)
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif o < 0x20 and ch != "\t" or o == 0x7F:
            out.append({"\n": "\\n", "\r": "\\r"}.get(ch, f"\\u{o:04X}"))
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def value(v) -> str:
    """One TOML value: string, bool, integer, float, list or inline table."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"{v!r} has no TOML form here")
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{key(k)} = {value(x)}" for k, x in v.items()) + " }" if v else "{}"
    raise TypeError(f"{type(v).__name__} has no TOML form")


def key(k) -> str:
    k = str(k)
    return k if k and all(c.isascii() and (c.isalnum() or c in "_-") for c in k) else _string(k)


def register_row(r: Register) -> str:
    parts = []
    for f in fields(Register):
        v = getattr(r, f.name)
        if f.name not in _ALWAYS and v == _DEFAULTS[f.name]:
            continue
        if f.name == "words" and r.type != "str":
            continue  # given by the type
        if f.name == "addr":
            parts.append(f"addr = 0x{v:04X}")
        else:
            parts.append(f"{f.name} = {value(v)}")
    return "  { " + ", ".join(parts) + " },"


def to_toml(m: RegisterMap, header: str = "") -> str:
    """The map's TOML text; `header` (lines without '#') goes first as comments."""
    out = [f"# {line}".rstrip() for line in header.splitlines()]
    out.append("registers = [")
    out += [register_row(r) for _a, r in sorted((*m.registers.items(), *m.inputs.items()),
                                               key=lambda ar: (ar[0], ar[1].table))]
    out += ["]", "", "[model]"]
    out += [f"{key(k)} = {value(v)}" for k, v in m.model.to_table().items()]
    if m.exceptions:
        out += ["", "[exceptions]"]
        out += [f'"0x{c:02X}" = {value(e)}' for c, e in sorted(m.exceptions.items())]
    for name, table in m.enums.items():
        out += ["", f"[enums.{key(name)}]"]
        out += [f'"{k}" = {value(e)}' for k, e in sorted(table.items())]
    for name, defs in m.bits.items():
        out += ["", f"[bits.{key(name)}]"]
        for d in defs:
            k = str(d["lo"]) if d["lo"] == d["hi"] else f"{d['lo']}-{d['hi']}"
            if "values" not in d:  # written as a plain name, read back without values
                out.append(f'"{k}" = {value(d["name"])}')
                continue
            spec = {"name": d["name"], "values": {str(v): t for v, t in d["values"].items()}}
            mn = d.get("mnemonic")
            if mn:  # the loader shows a flag as "OL1 — Motor overload": written back as its two fields
                spec = {"name": d["name"].removeprefix(f"{mn} — "), "mnemonic": mn, "values": spec["values"]}
            out.append(f'"{k}" = {value(spec)}')
    return "\n".join(out) + "\n"
