"""A register map from a plain CSV, the table plants keep in a spreadsheet.

    # model: sdm230                 <- optional lines before the header: model id, name, address base
    # base: 1
    address,name,type,scale,unit,access,description
    0x0000,Voltage,float32,,V,R,Line to neutral volts
    2524H,Output frequency,u16,0.01,Hz,R,
    30007,...                       <- with `# base: modicon` (or --map-base modicon)

Columns (header names are case-insensitive; the first two are required, the rest optional,
unknown columns are ignored): address, name, type, scale, unit, access, description, id,
word_order (ABCD / CDAB / BADC / DCBA or big / little), words (a string's length in registers),
min, max, default, section, table (holding / input: a device with both at one address; a
Modicon address says it itself).  Separators: comma, semicolon (then "0,1" is a decimal comma too) or
tab.  Addresses: hex (0x2524, 2524H) or decimal; decimal and hex alike count from 0 unless the
file or --map-base says 1 (or modicon: 4xxxx holding, 3xxxx input registers, from 1).
"""

from __future__ import annotations

import csv
import io
import os
import re

from ..tables import MapError, RegisterMap, map_from_doc
from .common import model_id_of, parse_address, parse_base, parse_number, parse_order, parse_type, read_text

# header name -> the column it is
_COLUMNS = {
    "address": "address", "addr": "address", "register": "address", "reg": "address", "offset": "address",
    "name": "name", "label": "name", "tag": "name",
    "type": "type", "data_type": "type", "datatype": "type", "format": "type",
    "scale": "scale", "factor": "scale", "multiplier": "scale", "gain": "scale",
    "unit": "unit", "units": "unit", "uom": "unit", "unit_of_measurement": "unit",
    "access": "access", "rw": "access", "r/w": "access", "mode": "access",
    "description": "note", "desc": "note", "comment": "note", "note": "note", "notes": "note",
    "id": "id", "parameter": "id", "param": "id",
    "word_order": "order", "order": "order", "byte_order": "order", "swap": "order", "endian": "order",
    "words": "words", "length": "words", "size": "words",
    "min": "min", "max": "max", "default": "default", "section": "section",
    "table": "table", "space": "table", "input_type": "table", "register_type": "table", "kind": "table",
}
_TABLES = {"holding": "holding", "h": "holding", "hr": "holding", "4x": "holding", "input": "input", "i": "input",
           "ir": "input", "3x": "input", "": ""}
_ACCESS = {"r": "R", "ro": "R", "read": "R", "w": "W", "wo": "W", "write": "W", "rw": "RW", "r/w": "RW",
           "wr": "RW", "read/write": "RW", "reserved": "reserved", "": "RW"}
_DIRECTIVE = re.compile(r"^#\s*(model|id|name|base)\s*[:=]\s*(.*?)\s*$", re.I)


def _delimiter(header: str) -> str:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    return max(counts, key=counts.get) if any(counts.values()) else ","


def load_csv(path: str, base: str | None = None) -> list[RegisterMap]:
    """The map in CSV file `path` (see the module doc); `base` (from --map-base) wins over the file's."""
    text = read_text(path)
    lines = text.splitlines()
    model = {"id": model_id_of(path), "manual": os.path.basename(path)}
    file_base = "0"
    first = 0
    for first, line in enumerate(lines):  # noqa: B007 - the header's line is where the loop stops
        s = line.strip()
        if not s:
            continue
        if not s.startswith("#"):
            break
        m = _DIRECTIVE.match(s)
        if m:
            key, value = m[1].lower(), m[2].strip().strip('"')
            if key == "base":
                try:
                    file_base = parse_base(value, "base")
                except ValueError as e:
                    raise MapError(f"{path}: line {first + 1}: {e}") from None
            elif value:
                model["name" if key == "name" else "id"] = value
    else:
        raise MapError(f"{path}: no header line (address,name,type,scale,unit,access,description)")
    base = base or file_base
    delim = _delimiter(lines[first])
    reader = csv.reader(io.StringIO("\n".join(lines[first:])), delimiter=delim)
    try:
        return _read(path, reader, model, first, base, delim)
    except csv.Error as e:  # a field over csv.field_size_limit(), a NUL byte, a quote left open
        raise MapError(f"{path}: line {first + reader.line_num}: not a CSV row ({e})") from None


def _read(path: str, reader, model: dict, first: int, base: str, delim: str) -> list[RegisterMap]:
    """The header and the rows under it (`first`: the header's line index)."""
    header = next(reader)
    cols: dict[str, int] = {}
    for k, h in enumerate(header):
        key = _COLUMNS.get(h.strip().lower().replace(" ", "_").replace("-", "_"))
        if key and key not in cols:
            cols[key] = k
    if "address" not in cols or "name" not in cols:
        seen = ", ".join(h.strip() for h in header)[:120]
        raise MapError(f"{path}: line {first + 1}: the header needs an address and a name column (found: {seen})")
    rows, places = [], []
    for cells in reader:
        lineno = first + reader.line_num
        if not any(c.strip() for c in cells) or cells[0].lstrip().startswith("#"):
            continue
        where = f"line {lineno}"
        try:
            rows.append(_row(cells, cols, base, delim == ";", os.path.basename(path), lineno))
        except ValueError as e:
            raise MapError(f"{path}: {where}: {e}") from None
        places.append(where)
    if not rows:
        raise MapError(f"{path}: no register rows under the header")
    return [map_from_doc({"model": model, "registers": rows}, path, places)]


def _row(cells: list[str], cols: dict[str, int], base: str, comma_decimal: bool, fname: str, lineno: int) -> dict:
    def cell(key: str) -> str:
        k = cols.get(key)
        return cells[k].strip() if k is not None and k < len(cells) else ""

    name = cell("name")
    if not name:
        raise ValueError("name is empty")
    row: dict = {"addr": parse_address(cell("address"), base), "name": name}
    table = _TABLES.get(cell("table").lower())
    if table is None:
        raise ValueError(f"table {cell('table')[:40]!r} (holding or input)")
    if base == "modicon":  # 3xxxx input, 4xxxx holding: the notation says which table
        table = "input" if cell("address").lstrip().startswith("3") else "holding"
    if table:
        row["table"] = table
    typ, wo, bo = parse_type(cell("type"))
    row["type"] = typ
    if cell("order"):
        wo, bo = parse_order(cell("order"))
    if wo and wo != "big":
        row["word_order"] = wo
    if bo and bo != "big":
        row["byte_order"] = bo
    if typ == "str":
        if not cell("words"):
            raise ValueError("a string needs its length in registers (a words column)")
        row["words"] = int(parse_number(cell("words"), "words"))
    if cell("scale"):
        row["scale"] = float(parse_number(cell("scale"), "scale", comma_decimal))
    access = cell("access").lower().replace(" ", "")
    if access not in _ACCESS:
        raise ValueError(f"access {cell('access')[:40]!r} (one of R, W, RW, reserved)")
    row["access"] = "R" if not access and table == "input" else _ACCESS[access]  # input registers: read-only
    for key in ("unit", "id", "note"):
        if cell(key):
            row[key] = cell(key)
    for key in ("min", "max", "default"):
        if cell(key):
            v = parse_number(cell(key), key)
            if not isinstance(v, int):
                raise ValueError(f"{key} {cell(key)[:40]!r} must be a whole raw value")
            row[key] = v
    row["section"] = cell("section") or f"{fname} line {lineno}"
    return row
