"""`--param KEY=VALUE` for `sniffer simulate`: change one thing about a scenario.

KEY is a Scenario field (`poll_period_ms=50`) or a unit's field
(`unit2.rated_current_a=7.5`, see UnitSpec).  Values are read as Python
literals and must have the field's type, so a typo is an error, not a
silently different bus.  This is how a user records "the same line after a
drive parameter changed" for `sniffer diff`.
"""

from __future__ import annotations

import ast
import dataclasses

from sniffer.simulator.scenario import Scenario


class OverrideError(ValueError):
    pass


def _value(text: str, current, key: str):
    try:
        v = ast.literal_eval(text)
    except (ValueError, SyntaxError):
        v = text
    if isinstance(current, bool) or current is None:
        ok = isinstance(v, type(current)) if current is not None else True
    elif isinstance(current, float):
        ok = isinstance(v, (int, float)) and not isinstance(v, bool)
        v = float(v) if ok else v
    else:
        ok = isinstance(v, type(current))
    if not ok:
        raise OverrideError(f"--param {key}: {text!r} is not a {type(current).__name__}")
    return v


def apply(sc: Scenario, items: list[str] | None) -> Scenario:
    for item in items or []:
        key, sep, text = item.partition("=")
        if not sep:
            raise OverrideError(f"--param {item!r}: expected KEY=VALUE")
        if key.startswith("unit") and "." in key:
            u_s, _, field = key[4:].partition(".")
            try:
                unit = int(u_s)
            except ValueError:
                raise OverrideError(f"--param {key}: expected unitN.field") from None
            units = list(sc.units)
            for i, spec in enumerate(units):
                if spec.unit == unit:
                    if field not in {f.name for f in dataclasses.fields(spec)} or field == "unit":
                        raise OverrideError(f"--param {key}: units have no field {field!r}")
                    units[i] = dataclasses.replace(spec, **{field: _value(text, getattr(spec, field), key)})
                    break
            else:
                raise OverrideError(f"--param {key}: scenario {sc.name!r} has no unit {unit}")
            sc = dataclasses.replace(sc, units=tuple(units))
        else:
            if key not in {f.name for f in dataclasses.fields(sc)} or key in ("name", "units", "polls"):
                raise OverrideError(f"--param {key}: scenarios have no such setting")
            sc = dataclasses.replace(sc, **{key: _value(text, getattr(sc, key), key)})
    return sc
