"""Register-map files (TOML, docs/register-map-format.md) -> lookup tables.

One loader for the built-in drive models and for `--model-file`; the lint
(`lint()`) is what the table tests run on every map.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from sniffer.tomlfile import read_toml


class MapError(ValueError):
    """A register-map file that cannot be used (one clear line)."""


WIDTH = {"u16": 1, "s16": 1, "u32": 2, "s32": 2}
ACCESS = {"R", "W", "RW", "reserved"}


@dataclass(slots=True)
class Register:
    addr: int
    id: str
    name: str
    type: str = "u16"
    scale: float = 1.0
    unit: str = ""
    access: str = "RW"
    enum: str | None = None
    bits: str | None = None
    min: int | None = None
    max: int | None = None
    default: int | None = None
    scale_by: dict | None = None
    scale_rule: str | None = None
    word_order: str = "big"
    section: str = ""
    note: str = ""

    @property
    def width(self) -> int:
        return WIDTH[self.type]


@dataclass
class RegisterMap:
    model: dict
    registers: dict[int, Register]
    enums: dict[str, dict[int, dict]]
    bits: dict[str, list[dict]]
    exceptions: dict[int, dict]
    path: str = ""
    by_id: dict[str, Register] = field(default_factory=dict)

    @property
    def model_id(self) -> str:
        return self.model["id"]

    def enum_text(self, name: str, value: int) -> str | None:
        e = self.enums.get(name, {}).get(value)
        if e is None:
            return None
        return e["text"] + (f" ({e['detail']})" if e.get("detail") else "")

    def bits_text(self, name: str, value: int) -> str:
        parts = []
        for fdef in self.bits.get(name, []):
            lo, hi = fdef["lo"], fdef["hi"]
            v = (value >> lo) & ((1 << (hi - lo + 1)) - 1)
            vals = fdef.get("values")
            if vals:
                txt = vals.get(v)
                if txt is not None:
                    parts.append(f"{fdef['name']}={txt}" if hi > lo or len(vals) > 1 else txt)
                elif v:
                    parts.append(f"{fdef['name']}={v}")
            elif v:
                parts.append(fdef["name"] if hi == lo else f"{fdef['name']}={v}")
        return ", ".join(parts) if parts else "-"


def _int(key) -> int:
    return int(key, 0) if isinstance(key, str) else int(key)


def _parse_bits(table: dict) -> list[dict]:
    out = []
    for key, spec in table.items():
        lo_s, _, hi_s = str(key).partition("-")
        lo = int(lo_s)
        hi = int(hi_s) if hi_s else lo
        if isinstance(spec, str):
            out.append({"lo": lo, "hi": hi, "name": spec})
        else:
            vals = {_int(k): v for k, v in (spec.get("values") or {}).items()}
            out.append({"lo": lo, "hi": hi, "name": spec.get("name", f"bit{lo}"), "values": vals})
    out.sort(key=lambda d: d["lo"])
    return out


def load_map(path: str | Path) -> RegisterMap:
    path = str(path)
    doc = read_toml(path, MapError)
    model = doc.get("model")
    if not isinstance(model, dict) or not model.get("id"):
        raise MapError(f"{path}: no [model] table with an id")
    regs: dict[int, Register] = {}
    fields = set(Register.__slots__)
    for i, row in enumerate(doc.get("registers", [])):
        row = dict(row)
        count = int(row.pop("count", 1))
        stride = int(row.pop("stride", 1))
        unknown = set(row) - fields
        if unknown or "addr" not in row or "name" not in row:
            raise MapError(f"{path}: register row {i + 1}: bad keys {sorted(unknown) or 'addr/name missing'}")
        row.setdefault("id", "")
        for k in range(count):
            r = Register(**{**row, "addr": row["addr"] + k * stride})
            if count > 1:
                r.name = f"{row['name']} [{k}]"
            if r.type not in WIDTH:
                raise MapError(f"{path}: register 0x{r.addr:04X}: unknown type {r.type!r}")
            if r.addr in regs:
                raise MapError(f"{path}: register 0x{r.addr:04X} listed twice")
            regs[r.addr] = r
    enums = {
        name: {_int(k): ({"text": v} if isinstance(v, str) else dict(v)) for k, v in table.items()}
        for name, table in (doc.get("enums") or {}).items()
    }
    bits = {name: _parse_bits(table) for name, table in (doc.get("bits") or {}).items()}
    exc = {_int(k): ({"name": v} if isinstance(v, str) else dict(v)) for k, v in (doc.get("exceptions") or {}).items()}
    m = RegisterMap(model, regs, enums, bits, exc, path)
    m.by_id = {r.id: r for r in regs.values() if r.id}
    return m


def lint(m: RegisterMap) -> list[str]:
    """Problems that make a map untrustworthy: overlaps, dangling references, missing sections."""
    problems = []
    ids: dict[str, int] = {}
    for a, r in sorted(m.registers.items()):
        if not r.section:
            problems.append(f"0x{a:04X} {r.name}: no manual section")
        if r.access not in ACCESS:
            problems.append(f"0x{a:04X}: access {r.access!r}")
        for k in range(1, r.width):
            if a + k in m.registers:
                problems.append(f"0x{a:04X} ({r.type}) overlaps 0x{a + k:04X}")
        if r.enum and r.enum not in m.enums:
            problems.append(f"0x{a:04X}: enum {r.enum!r} not defined")
        if r.bits and r.bits not in m.bits:
            problems.append(f"0x{a:04X}: bits {r.bits!r} not defined")
        if r.scale_by and r.scale_by.get("addr") not in m.registers:
            problems.append(f"0x{a:04X}: scale_by register not in the map")
        for rid in [x.strip() for x in r.id.split("/") if x.strip()]:
            if rid in ids and ids[rid] != a:
                problems.append(f"id {rid} used at 0x{ids[rid]:04X} and 0x{a:04X}")
            ids[rid] = a
    return problems
