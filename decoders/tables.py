"""Register-map files (TOML, docs/register-map-format.md) -> lookup tables.

One loader for the built-in drive models and for `--model-file`; the lint
(`lint()`) is what the table tests run on every map.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from pathlib import Path

from decoders.tomlfile import read_toml

from . import regtypes
from .model_info import MAX_REGISTERS, ModelInfo, brief, is_int, is_number
from .regtypes import ORDERS, TEXT, TYPES, WIDTH


class MapError(ValueError):
    """A register-map file that cannot be used (one clear line)."""


ACCESS = {"R", "W", "RW", "reserved"}


@dataclass(slots=True)
class Register:
    """One row of a register map.  `type` is one of regtypes.TYPES (aliases such as "float32" are
    taken); `words` is the number of registers it takes: given by the type (0 = from the type),
    required for "str".  A map importer sets type, words and the two orders; a bad combination
    raises MapError."""

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
    byte_order: str = "big"
    words: int = 0
    section: str = ""
    note: str = ""
    table: str = ""  # "holding" or "input" where the device has both at one address; "": either

    def __post_init__(self) -> None:
        self.type = t = regtypes.canonical(self.type)
        where = f"register 0x{self.addr:04X}" if isinstance(self.addr, int) else "register"
        if t not in TYPES:
            raise MapError(f"{where}: unknown type {_show(t)} (one of {', '.join(TYPES)})")
        if t == TEXT:
            if not is_int(self.words) or not 1 <= self.words <= regtypes.MAX_WORDS:
                raise MapError(f"{where}: a str needs words = 1..{regtypes.MAX_WORDS} (registers of text)")
        elif not self.words:
            self.words = WIDTH[t]
        elif self.words != WIDTH[t]:
            raise MapError(f"{where}: words = {_show(self.words)}, but a {t} takes {WIDTH[t]}")
        for f in ("word_order", "byte_order"):
            if getattr(self, f) not in ORDERS:
                raise MapError(f"{where}: {f} {_show(getattr(self, f))} (big or little)")

    @property
    def width(self) -> int:
        """Registers the value takes (= words)."""
        return self.words

    def number(self, raw: int):
        """The number a raw bit pattern of this register stands for (signed, float), before scale."""
        t = self.type
        if t == "u16":
            return raw
        if t == "s16":
            return raw - 0x10000 if raw >= 0x8000 else raw
        return regtypes.number(t, raw, self.words)


@dataclass
class RegisterMap:
    model: ModelInfo
    registers: dict[int, Register]
    enums: dict[str, dict[int, dict]]
    bits: dict[str, list[dict]]
    exceptions: dict[int, dict]
    path: str = ""
    by_id: dict[str, Register] = field(default_factory=dict)
    _parts: dict[int, tuple[Register, int]] | None = field(default=None, repr=False)
    _part_addrs: list[int] | None = field(default=None, repr=False)
    inputs: dict[int, Register] = field(default_factory=dict)  # rows of table "input" (not in `registers`)
    _input_view: RegisterMap | None = field(default=None, repr=False)

    def view(self, space: str) -> RegisterMap:
        """The map a read or write of `space` ("holding" / "input") sees: the rows of that table and
        those of none.  `registers` holds the holding and the table-less rows, so it is the holding
        view; a map without input-only or holding-only rows is one view for both."""
        if space != "input":
            return self
        if self._input_view is None:
            if not self.inputs and all(not r.table for r in self.registers.values()):
                self._input_view = self
            else:
                regs = {a: r for a, r in self.registers.items() if not r.table}
                regs.update(self.inputs)
                v = RegisterMap(self.model, dict(sorted(regs.items())), self.enums, self.bits, self.exceptions,
                                self.path)
                v.by_id = {r.id: r for r in regs.values() if r.id}
                v._input_view = v
                self._input_view = v
        return self._input_view

    @property
    def model_id(self) -> str:
        return self.model.id

    @property
    def parts(self) -> dict[int, tuple[Register, int]]:
        """address -> (the multi-register row holding it, the word's index in it), for every register
        of every row of more than one word (built on first use: the rows must be complete by then)."""
        if self._parts is None:
            self._parts = {r.addr + k: (r, k) for r in self.registers.values() if r.words > 1
                           for k in range(r.words)}
        return self._parts

    def any_part(self, addr: int, n: int) -> bool:
        """Does any register of addr..addr+n-1 belong to a row of more than one word?"""
        parts = self.parts
        if not parts:
            return False
        starts = self._part_addrs
        if starts is None:
            starts = self._part_addrs = sorted(parts)
        i = bisect.bisect_left(starts, addr)
        return i < len(starts) and starts[i] < addr + n

    def covering(self, addr: int) -> tuple[Register, int] | None:
        """(row, word index) of the row whose value takes register `addr`: (row, 0) at its own address."""
        r = self.registers.get(addr)
        if r is not None and r.words == 1:
            return r, 0
        return self.parts.get(addr)

    def enum_text(self, name: str, value: int) -> str | None:
        """One form for every table: the manual's mnemonic (`text`) and its description (`detail`),
        or our `reading` where the manual prints only the mnemonic: "OL1 — Motor overload"."""
        e = self.enums.get(name, {}).get(value)
        if e is None:
            return None
        head, tail = e["text"], e.get("detail") or e.get("reading")
        if head and tail:
            return f"{head} — {tail}"
        return head or tail or "no text in the manual"

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


MAX_ADDR = 0xFFFF
TOP_LEVEL = ("registers", "model", "enums", "bits", "exceptions")
MAX_BIT = 63  # bit fields of a u64
_STR_FIELDS = ("id", "name", "unit", "enum", "bits", "scale_rule", "section", "note")
_INT_FIELDS = ("min", "max", "default")


def _show(v) -> str:
    return brief(v, 60)


def _int(key) -> int:
    """A table key or value that names a number: an int, or a string "12" / "-3" / "0x0C"; ValueError if not."""
    if is_int(key):
        return key
    if isinstance(key, str):
        t = key.strip()
        body = t[1:] if t[:1] == "-" else t
        if body[:2].lower() == "0x" and 2 < len(body) <= 18 and all(c in "0123456789abcdefABCDEF" for c in body[2:]):
            return int(t, 16)
        if body.isascii() and body.isdigit() and len(body) <= 18:
            return int(t, 10)
    raise ValueError(f"{_show(key)} is not a number (decimal or 0x.. hex)")


class _Check:
    """Type and range checks of one file, each failure one MapError line naming the place."""

    def __init__(self, path: str, places: list[str] | None = None) -> None:
        self.path = path
        self.places = places

    def fail(self, where: str, what: str):
        raise MapError(f"{self.path}: {where}: {what}")

    def table(self, v, where: str) -> dict:
        if not isinstance(v, dict):
            self.fail(where, f"must be a table, not {_show(v)}")
        return v

    def key(self, k, where: str, lo: int, hi: int) -> int:
        try:
            n = _int(k)
        except ValueError as e:
            self.fail(where, f"key {e}")
        if not lo <= n <= hi:
            self.fail(where, f"key {_show(k)} is outside {lo}..{hi}")
        return n

    def text(self, d: dict, field: str, where: str, required: bool = False) -> None:
        if field not in d:
            if required:
                self.fail(where, f"{field} missing")
            return
        if not isinstance(d[field], str) or (required and not d[field].strip()):
            self.fail(where, f"{field} must be a{' non-empty' if required else ''} string, not {_show(d[field])}")

    def int_in(self, d: dict, field: str, where: str, lo: int, hi: int) -> None:
        if field in d and (not is_int(d[field]) or not lo <= d[field] <= hi):
            self.fail(where, f"{field} must be an integer in {lo}..{hi}, not {_show(d[field])}")

    def model(self, table) -> ModelInfo:
        """The [model] table: every key known, each value of its kind (decoders/model_info.py)."""
        return ModelInfo.from_table(table, lambda text: MapError(f"{self.path}: {text}"),
                                    top_level=tuple(k for k in TOP_LEVEL if k != "model"))

    def place(self, i: int) -> str:
        """How an error names register row `i` (an imported file names its own rows: "row 7")."""
        return self.places[i] if self.places else f"register row {i + 1}"

    def row(self, i: int, row) -> tuple[dict, int, int]:
        """A register row's fields (count/stride removed) after every check, and its count and stride."""
        where = self.place(i)
        row = dict(self.table(row, where))
        count, stride = row.pop("count", 1), row.pop("stride", 1)
        unknown = set(row) - set(Register.__slots__)
        if unknown or "addr" not in row or "name" not in row:
            self.fail(where, f"bad keys {_show(sorted(unknown)) if unknown else 'addr/name missing'}")
        self.int_in(row, "addr", where, 0, MAX_ADDR)
        where = f"{self.place(i)} (0x{row['addr']:04X})"
        if row.get("table", "") not in ("", "holding", "input"):
            self.fail(where, f"table {_show(row['table'])} (holding or input)")
        for f in _STR_FIELDS:
            self.text(row, f, where, required=f == "name")
        for f in _INT_FIELDS:  # the number before scale: a u64's can be that large
            self.int_in(row, f, where, -(1 << 64), 1 << 64)
        t = row["type"] = regtypes.canonical(row.get("type", "u16"))
        if t not in TYPES:
            self.fail(where, f"unknown type {_show(t)} (one of {', '.join(TYPES)})")
        words = row.get("words", 0)
        if t == TEXT:
            if not is_int(words) or not 1 <= words <= regtypes.MAX_WORDS:
                self.fail(where, f"a str needs words = 1..{regtypes.MAX_WORDS} (registers of text), "
                                 f"not {_show(words) if 'words' in row else 'none'}")
            if "word_order" in row:
                self.fail(where, "word_order does not apply to a str (its characters follow the addresses)")
        elif "words" in row and words != WIDTH[t]:
            self.fail(where, f"words = {_show(words)}, but a {t} takes {WIDTH[t]}")
        if row.get("access", "RW") not in ACCESS:
            self.fail(where, f"access {_show(row['access'])} (one of {', '.join(sorted(ACCESS))})")
        for f in ("word_order", "byte_order"):
            if row.get(f, "big") not in ORDERS:
                self.fail(where, f"{f} {_show(row[f])} (big or little)")
        if "scale" in row and not is_number(row["scale"]):
            self.fail(where, f"scale must be a finite number, not {_show(row['scale'])}")
        if "scale_by" in row:
            sb = self.table(row["scale_by"], f"{where} scale_by")
            self.int_in(sb, "addr", f"{where} scale_by", 0, MAX_ADDR)
            if "addr" not in sb or not is_number(sb.get("full")) or sb["full"] <= 0:
                self.fail(where, "scale_by needs addr and a positive number full")
        if not is_int(count) or not 1 <= count <= MAX_REGISTERS:
            self.fail(where, f"count must be an integer in 1..{MAX_REGISTERS}, not {_show(count)}")
        if not is_int(stride) or not 1 <= stride <= MAX_ADDR:
            self.fail(where, f"stride must be an integer in 1..{MAX_ADDR}, not {_show(stride)}")
        last = row["addr"] + (count - 1) * stride + (words if t == TEXT else WIDTH[t]) - 1
        if last > MAX_ADDR:
            what = f"count {count} x stride {stride}" if count > 1 else f"a {t} here"
            self.fail(where, f"{what} runs past register 0xFFFF")
        return row, count, stride

    def entry(self, v, where: str, need: str, required: bool) -> dict:
        """An enum / exception entry: a string (its `need` field), or a table of strings."""
        if isinstance(v, str):
            return {need: v}
        self.table(v, where)
        if required and need not in v:
            self.fail(where, f"{need} missing")
        for f in (need, "text", "detail", "name", "reading", "section"):
            self.text(v, f, where)
        if "unlisted" in v and not isinstance(v["unlisted"], bool):
            self.fail(where, f"unlisted must be true or false, not {_show(v['unlisted'])}")
        return dict(v)

    def bits(self, name: str, table) -> list[dict]:
        where = f"[bits.{name}]"
        out = []
        for key, spec in self.table(table, where).items():
            lo_s, _, hi_s = str(key).partition("-")
            if not all(p.isascii() and p.isdigit() and len(p) <= 2 for p in ([lo_s, hi_s] if hi_s else [lo_s])):
                self.fail(where, f"key {_show(key)} is not a bit number or lo-hi range")
            lo, hi = int(lo_s), int(hi_s or lo_s)
            if not lo <= hi <= MAX_BIT:
                self.fail(where, f"key {_show(key)}: bits must be 0..{MAX_BIT}, low first")
            if isinstance(spec, str):
                out.append({"lo": lo, "hi": hi, "name": spec})
                continue
            self.table(spec, f"{where} {key}")
            for f in ("name", "mnemonic", "section", "note"):
                self.text(spec, f, f"{where} {key}")
            values = self.table(spec.get("values") or {}, f"{where} {key} values")
            vals = {self.key(k, f"{where} {key} values", -(1 << 32), 1 << 32): v for k, v in values.items()}
            if not all(isinstance(v, str) for v in vals.values()):
                self.fail(f"{where} {key} values", "every value must be a string")
            name = spec.get("name", f"bit{lo}")
            if spec.get("mnemonic"):  # a fault/alarm flag: shown as its enums are, "OL1 — Motor overload"
                name = f"{spec['mnemonic']} — {name}"
            out.append({"lo": lo, "hi": hi, "name": name, "values": vals, "mnemonic": spec.get("mnemonic", "")})
        out.sort(key=lambda d: d["lo"])
        return out


def load_map(path: str | Path) -> RegisterMap:
    """The map in `path`, every row and table checked first; MapError (one line: file and place) if not usable."""
    path = str(path)
    doc = read_toml(path, MapError)
    model = doc.get("model")
    if model is None or (isinstance(model, dict) and "id" not in model):  # the id is the file's stem, as
        import os  # for a CSV or YAML map, unless the file names one

        doc["model"] = {**(model or {}), "id": os.path.splitext(os.path.basename(path))[0] or "map"}
    return map_from_doc(doc, path)


def map_from_doc(doc: dict, path: str, places: list[str] | None = None) -> RegisterMap:
    """A register map from a document shaped as the TOML file (an imported CSV / YAML file builds one);
    `places` names each register row in errors (default "register row N")."""
    c = _Check(path, places)
    unknown = sorted(set(doc) - set(TOP_LEVEL))
    if unknown:
        c.fail("top level", f"unknown keys {_show(unknown)} (known: {', '.join(TOP_LEVEL)})")
    model = c.model(doc.get("model"))
    rows = _Rows(c, model)
    rows.add_all(doc.get("registers", []))
    rows.check_inside()
    enums = {}
    for name, table in c.table(doc.get("enums") or {}, "[enums]").items():
        where = f"[enums.{name}]"
        enums[name] = {c.key(k, where, -(1 << 32), 1 << 32): c.entry(v, f"{where} {k}", "text", True)
                       for k, v in c.table(table, where).items()}
    bits = {name: c.bits(name, table) for name, table in c.table(doc.get("bits") or {}, "[bits]").items()}
    exc = {c.key(k, "[exceptions]", 0, 255): c.entry(v, f"[exceptions] {k}", "name", False)
           for k, v in c.table(doc.get("exceptions") or {}, "[exceptions]").items()}
    m = RegisterMap(model, rows.regs, enums, bits, exc, path, inputs=rows.inputs)
    m.by_id = {r.id: r for r in (*rows.inputs.values(), *rows.regs.values()) if r.id}
    problems = lint(m, sections=False)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise MapError(f"{path}: {problems[0]}{more}")
    return m


class _Rows:
    """The register rows of one file, checked and expanded (count/stride) into its two tables: `regs` (holding
    and table-less rows) and `inputs` (rows of table "input": the same address may be a holding row too)."""

    def __init__(self, c: _Check, model: ModelInfo) -> None:
        self.c = c
        self.orders = {"word_order": model.word_order, "byte_order": model.byte_order}  # the rows' defaults
        self.regs: dict[int, Register] = {}
        self.inputs: dict[int, Register] = {}
        self.row_of: dict[tuple[str, int], int] = {}  # (table, address) -> the row index that has it

    def add_all(self, rows) -> None:
        if not isinstance(rows, list):
            self.c.fail("registers", f"must be an array of tables, not {_show(rows)}")
        checked = [self.c.row(i, row) for i, row in enumerate(rows)]
        total = sum(count for _row, count, _stride in checked)
        if total > MAX_REGISTERS:
            self.c.fail("registers", f"{total} registers: more than the {MAX_REGISTERS} addresses a unit has")
        for i, (row, count, stride) in enumerate(checked):
            self.add(i, row, count, stride)

    def add(self, i: int, row: dict, count: int, stride: int) -> None:
        row.setdefault("id", "")
        for f, v in self.orders.items():
            if not (f == "word_order" and row["type"] == TEXT):
                row.setdefault(f, v)
        for k in range(count):
            r = Register(**{**row, "addr": row["addr"] + k * stride})
            if count > 1:
                r.name = f"{row['name']} [{k}]"
            tables = ("holding", "input") if not r.table else (r.table,)  # a table-less row is in both
            clash = [t for t in tables if (t, r.addr) in self.row_of]
            if clash:
                self._fail_at(i, f"register 0x{r.addr:04X} listed twice", also=self.row_of[(clash[0], r.addr)])
            (self.inputs if r.table == "input" else self.regs)[r.addr] = r
            for t in tables:
                self.row_of[(t, r.addr)] = i

    def check_inside(self) -> None:
        """A value of several registers owns them all, in its table: no other row may sit inside it."""
        for t in ("holding", "input"):
            rows_t = {a: r for a, r in (*self.regs.items(), *self.inputs.items()) if r.table in ("", t)}
            for a, r in rows_t.items():
                for k in range(1, r.words):
                    if a + k in rows_t:
                        self._fail_at(self.row_of[(t, a + k)], f"register 0x{a + k:04X} is inside 0x{a:04X} "
                                                               f"({r.name}, a {r.type} of {r.words} registers)")

    def _fail_at(self, i: int, what: str, also: int | None = None):
        """A file that names its rows (an import) says which; a TOML map's line is the register's address."""
        places = self.c.places
        if not places:
            raise MapError(f"{self.c.path}: {what}")
        more = f" (also {self.c.place(also)})" if also is not None else ""
        raise MapError(f"{self.c.path}: {places[i]}: {what}{more}")


def lint(m: RegisterMap, sections: bool = True) -> list[str]:
    """Problems that make a map untrustworthy: overlaps, dangling references, missing sections.

    Every map is loaded through it (`map_from_doc` refuses one with problems); a user's map may
    leave out the manual sections (`sections=False`), the built-in maps' test holds them to it."""
    problems = []
    ids: dict[str, int] = {}
    for a, r in sorted((*m.registers.items(), *m.inputs.items()), key=lambda ar: (ar[0], ar[1].table)):
        if sections and not r.section:
            problems.append(f"0x{a:04X} {r.name}: no manual section")
        problems += _value_problems(a, r) + _reference_problems(m, a, r)
        for rid in [x.strip() for x in r.id.split("/") if x.strip()]:
            if rid in ids and ids[rid] != a and not r.table:
                problems.append(f"id {rid} used at 0x{ids[rid]:04X} and 0x{a:04X}")
            ids[rid] = a
    return problems


def _value_problems(a: int, r: Register) -> list[str]:
    """What one row says about its values that cannot be: scale 0, min > max, limits its type cannot hold, an
    access an input register cannot have."""
    out = []
    if r.scale == 0:
        out.append(f"0x{a:04X}: scale 0 makes every value 0")
    if r.min is not None and r.max is not None and r.min > r.max:
        out.append(f"0x{a:04X}: min {r.min} > max {r.max}")
    span = regtypes.raw_range(r.type)
    for f in ("min", "max", "default"):
        v = getattr(r, f)
        if span is not None and v is not None and not span[0] <= v <= span[1]:
            out.append(f"0x{a:04X}: {f} {v} is outside a {r.type} ({span[0]}..{span[1]})")
    if r.table == "input" and r.access in ("W", "RW"):
        out.append(f"0x{a:04X}: access {r.access} on an input register (Modbus input registers are read-only)")
    if r.access not in ACCESS:
        out.append(f"0x{a:04X}: access {r.access!r}")
    return out


def _reference_problems(m: RegisterMap, a: int, r: Register) -> list[str]:
    """What one row names that is not there or cannot apply, or runs into: the next rows, an enum, bits (a float
    or a text takes neither), its scale register."""
    out = []
    for k in range(1, r.width):
        if a + k in (m.inputs if r.table == "input" else m.registers):
            out.append(f"0x{a:04X} ({r.type}) overlaps 0x{a + k:04X}")
    if r.enum and r.enum not in m.enums:
        out.append(f"0x{a:04X}: enum {r.enum!r} not defined")
    if r.bits and r.bits not in m.bits:
        out.append(f"0x{a:04X}: bits {r.bits!r} not defined")
    if r.type in regtypes.FLOATS or r.type == TEXT:  # a code or flags are integers; text has no scale
        for f in ("enum", "bits") + (("scale_by", "scale") if r.type == TEXT else ()):
            if getattr(r, f) not in (None, 1.0):
                out.append(f"0x{a:04X}: a {r.type} takes no {f}")
    for fdef in m.bits.get(r.bits or "", []):
        if fdef["hi"] >= 16 * r.words:
            out.append(f"0x{a:04X}: bits {r.bits!r} field {fdef['name']!r} past bit {16 * r.words - 1}")
    if r.scale_by and r.scale_by.get("addr") not in m.registers:
        out.append(f"0x{a:04X}: scale_by register not in the map")
    return out
