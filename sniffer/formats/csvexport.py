"""CSV export: OUT.csv (one row per frame) + OUT.points.csv (one row per decoded point); see rows.py.

The text is Arrow's CSV writer's (`quoting_style="needed"`), byte for byte, written here without pyarrow
(the core install has none): a header line of quoted names; strings always in double quotes (a quote
doubled inside), integers in decimal, booleans as true / false, empty cells for null, "\\n" after each
row; a float in its shortest round-trip digits, fixed-point from 1e-6 up to 1e10 (`3`, `0.000015`,
`1234567890`) and else with an exponent (`1e-7`, `1.5e+10`), `inf`, `-inf`, `nan`.  pandas, DuckDB
and spreadsheets read it as it is.  A batch of rows is formatted column by column (one list
comprehension per column) and written with one write.
"""

from __future__ import annotations

import os
from decimal import Decimal

from sniffer.formats.rows import FRAMES, POINTS
from sniffer.hot import HOT
from sniffer.formats.tables import TableSink


def float_text(v) -> str:
    """A float64 cell as Arrow writes it (double-conversion's shortest form, fixed for exponents -6..9)."""
    if v is None:
        return ""
    r = repr(float(v))
    if "n" in r:  # inf, -inf, nan (a nan has no sign here either)
        return r
    if "e" not in r and -1e10 < v < 1e10:  # Python's fixed form (1e-4 <= |v| < 1e16) where Arrow's is too
        return r[:-2] if r.endswith(".0") else r
    sign, shortest, exp = Decimal(r).as_tuple()  # the same shortest round-trip digits as Arrow's
    full = "".join(map(str, shortest))
    digits = full.rstrip("0")
    point = len(full) + exp  # the value is 0.DIGITS times 10**point
    lead = "-" if sign else ""
    e = point - 1
    if -6 <= e < 10:
        if point <= 0:
            return f"{lead}0.{'0' * -point}{digits}"
        if point >= len(digits):
            return lead + digits + "0" * (point - len(digits))
        return f"{lead}{digits[:point]}.{digits[point:]}"
    return f"{lead}{digits[0]}{'.' + digits[1:] if len(digits) > 1 else ''}e{'-' if e < 0 else '+'}{abs(e)}"


def _column(kind: str, col: tuple) -> list[str]:
    """One column's cells.  Floats: Python's repr, where it is Arrow's text but for a trailing ".0"
    (most values), else float_text; `None` has an "n" too."""
    if kind == "str":
        return ["" if v is None else (f'"{v}"' if '"' not in v else '"' + v.replace('"', '""') + '"') for v in col]
    if kind == "int":
        return ["" if v is None else str(v) for v in col]
    if kind == "float":
        return [float_text(v) if "e" in r or "n" in r or not 0 < r.find(".") <= 10
                else (r[:-2] if r[-2:] == ".0" else r) for v, r in zip(col, map(repr, col))]
    return ["" if v is None else ("true" if v else "false") for v in col]  # bool


def header(columns) -> bytes:
    """The header line: every column's name in double quotes."""
    return (",".join(f'"{name}"' for name, _ in columns) + "\n").encode()


# a batch's text written in C (sniffer/_hot.c csv_text); None: by csv_text_py, the reference
_CSV_TEXT = None if HOT is None else HOT.csv_text
_KINDS: dict[tuple, tuple[str, ...]] = {}


def csv_text(rows: list, columns) -> bytes:
    """Rows (tuples in the columns' order) -> their CSV lines, UTF-8."""
    if _CSV_TEXT is not None and type(rows) is list:
        kinds = _KINDS.get(columns)
        if kinds is None:
            kinds = _KINDS[columns] = tuple(kind for _, kind in columns)
        text = _CSV_TEXT(rows, kinds, float_text)
        if text is not None:  # None: a cell not of its column's plain type
            return text
    return csv_text_py(rows, columns)


def csv_text_py(rows: list, columns) -> bytes:
    """csv_text in Python: the reference."""
    cells = [_column(kind, col) for (_, kind), col in zip(columns, zip(*rows))]
    return ("\n".join(map(",".join, zip(*cells))) + "\n").encode()


class CsvSink(TableSink):
    TABLES = (FRAMES, POINTS)

    def __init__(self, frames_path, points_path) -> None:
        """Paths, or binary files (closed with the sink)."""
        super().__init__()
        self._files = [_open(frames_path)]
        try:
            self._files.append(_open(points_path))
            for fh, columns in zip(self._files, self.TABLES):
                fh.write(header(columns))
        except BaseException:
            for fh in self._files:
                fh.close()
            raise

    def start(self, info) -> None:
        super().start(info)
        for fh in self._files:  # a disk that is full already fails now, before the input is read
            fh.flush()

    def _put(self, table: int, rows: list) -> None:
        self._files[table].write(csv_text(rows, self.TABLES[table]))

    def _end(self) -> None:
        error = None
        for fh in self._files:
            try:
                fh.close()
            except BaseException as e:  # noqa: BLE001 - the other file is closed first; raised below
                error = error or e
        if error is not None:
            raise error


def _open(out):
    return open(out, "wb") if isinstance(out, (str, os.PathLike)) else out


def open_sink(fmt: str, path: str, parts: list[str]) -> CsvSink:
    """The Csv sink writing its part files (named in the table of sniffer.formats)."""
    return CsvSink(*parts)
