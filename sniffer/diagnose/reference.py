"""`sniffer diagnose --params REFERENCE`: a drive's parameter set to hold this capture's values against.

REFERENCE is a CSV (a header `unit,register,value`; a register is the manual's id such as Cn-02, or an
address: 769, 0x0301 or 0301H; a value as the sniffer shows it, in engineering units), or an earlier
capture of the same line (any input `replay` reads, decoded with the same flags: the last value it read
or wrote of each holding register with a manual id).  `Reference.compare` turns the differences into
params_changed findings, one per unit.
"""

from __future__ import annotations

import csv
import io
import os
import math

from sniffer.codes import WARNING
from sniffer.events import CaptureError
from sniffer.diagnose.finding import Finding
from sniffer.inputs import CAPS, finite, open_regular, read_text

KIND = "a parameter set"

MAX_ROWS = 100_000


class ReferenceError(CaptureError):
    """A --params file that cannot be read (one line, exit 2)."""


def _address(text: str) -> int | None:
    t = text.strip()
    try:
        if t.lower().startswith("0x"):
            return int(t, 16)
        if t.upper().endswith("H"):
            return int(t[:-1], 16)
        return int(t)
    except ValueError:
        return None


class Reference:
    """Values per (link, unit, register): a register by id until the unit's map resolves it."""

    def __init__(self, source: str, rows: list[tuple[str, int, str, object]]) -> None:
        self.source = source
        self.rows = rows  # (link, unit, register id or address text, value)
        self._resolved: dict[tuple, dict[int, tuple]] = {}  # (link, unit) -> addr -> (name, value)
        self._unknown: dict[tuple, tuple[str, list[str]]] = {}  # (link, unit) -> (model, names its map lacks)

    def addresses(self, link, unit: int, model: str | None) -> dict[int, tuple]:
        """`model`: the one the unit's frame was decoded with."""
        key = (link.name, unit)
        got = self._resolved.get(key)
        if got is None:
            got = self._resolved[key] = self._resolve(link, unit, model)
        return got

    def _resolve(self, link, unit: int, model: str | None) -> dict[int, tuple]:
        by_id = getattr(getattr(link.decoder(model), "map", None), "by_id", None) or {}
        out = {}
        for ln, u, name, value in self.rows:
            if u != unit or (ln and ln != link.name):
                continue
            r = by_id.get(name)
            addr = r.addr if r is not None else _address(name)
            if addr is not None:
                out[addr] = (name if r is not None or not by_id else name, value)
            else:
                self._unknown.setdefault((link.name, unit), (model or "generic", []))[1].append(name)
        return out

    def notes(self) -> list[str]:
        """What of the reference was compared with nothing, in words: rows naming a register the unit's map does
        not have, and units the capture never heard (said, not dropped: a typo would hide a changed value)."""
        where = os.path.basename(self.source)
        out = []
        for (ln, unit), (model, names) in sorted(self._unknown.items(), key=lambda kv: (kv[0][0], kv[0][1])):
            shown = ", ".join(repr(n[:40]) for n in names[:5])
            shown += f" and {len(names) - 5} more" if len(names) > 5 else ""
            rows = f"{len(names)} rows" if len(names) != 1 else "1 row"
            verb = "name" if len(names) != 1 else "names"
            out.append(f"--params {where}: {rows} of unit {unit}{f' on {ln}' if ln else ''} {verb} no register of "
                       f"its map ({model}) and no address: {shown}; not compared")
        heard = {u for _, u in self._resolved} | {u for _, u in self._unknown}
        missing = sorted({u for _, u, _, _ in self.rows} - heard)
        if missing:
            units = ", ".join(map(str, missing[:10]))
            units += f" and {len(missing) - 10} more" if len(missing) > 10 else ""
            out.append(f"--params {where}: unit{'s' if len(missing) > 1 else ''} {units} never answered in the "
                       "capture; not compared")
        return out

    def compare(self, d, read: dict) -> list[Finding]:
        out = []
        for (name, unit), want in self._resolved.items():
            got = read.get((name, unit), {})
            diffs = []
            frames = []
            for addr, (pname, ref) in sorted(want.items()):
                if addr not in got:
                    continue
                value, text, index, eng = got[addr]
                if _same(ref, value):
                    continue
                diffs.append({"parameter": pname, "reference": ref, "now": value, "unit": eng, "frame": index})
                frames.append(index)
            if not diffs:
                continue
            listed = ", ".join(f"{x['parameter']} {x['reference']} -> {x['now']}{' ' + x['unit'] if x['unit'] else ''}"
                               for x in diffs[:5])
            more = f" and {len(diffs) - 5} more" if len(diffs) > 5 else ""
            link = d.links.get(name)
            out.append(Finding(
                "params_changed", WARNING, unit=unit, link=name, frames=frames,
                t_start=d.seconds(link.first_ns) if link else None, t_end=d.seconds(link.last_ns) if link else None,
                evidence={"reference": self.source, "compared": sum(1 for a in want if a in got),
                          "changed": len(diffs), "changes": diffs[:20]},
                text=f"Unit {unit}'s parameters differ from {os.path.basename(self.source)}: {listed}{more}.",
                action="Check who changed them and why (a replaced drive, a keypad change, the PLC's writes); put the "
                       "reference values back, or update the reference if the change was meant."))
        return out


def _same(a, b) -> bool:
    try:
        x, y = float(a), float(b)
    except (TypeError, ValueError):
        return str(a).strip() == str(b).strip()
    return math.isclose(x, y, rel_tol=1e-6, abs_tol=1e-9)


def load_csv(path: str) -> Reference:
    rows = []
    text = read_text(path, CAPS[KIND], KIND, ReferenceError, bom=True)
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        fields = {(h or "").strip().lower(): h for h in reader.fieldnames or ()}
        if not {"unit", "register", "value"} <= set(fields):
            raise ReferenceError(f"--params {path}: a CSV needs the columns unit, register, value "
                                 f"(found: {', '.join(fields) or 'none'})")
        for i, r in enumerate(reader, 2):
            if len(rows) >= MAX_ROWS:
                break
            unit_text = (r.get(fields["unit"]) or "").strip()
            link, _, unit_text = unit_text.rpartition(":")
            try:
                unit = int(unit_text, 0)
            except ValueError:
                raise ReferenceError(f"--params {path}: line {i}: unit {unit_text[:20]!r} is not a number") \
                    from None
            value = (r.get(fields["value"]) or "").strip()
            try:
                float(value)
            except ValueError:
                pass  # a value shown as text (an enum's name) is compared as text
            else:  # a number is finite: nan, inf, 1e400 hold against nothing a drive reads back
                value = finite(value, f"--params {path}: line {i}: value", ReferenceError)
            rows.append((link, unit, (r.get(fields["register"]) or "").strip(), value))
    except csv.Error as e:
        raise ReferenceError(f"--params {path}: not a CSV ({e})") from None
    return Reference(path, rows)


def load_capture(path: str, spec) -> Reference:
    """The last value of each holding register with a manual id, read or written in an earlier capture."""
    from sniffer.sources.segset import replay_source as file_source
    from sniffer.capture.session import Session

    cspec = spec.with_(input=path, inputs=(path,))
    session = Session(cspec, file_source(cspec), [])
    last: dict[tuple, tuple] = {}
    settable: dict[tuple, bool] = {}
    for f in session:
        if f.role != "response" or not f.crc_ok or f.exception or not f.writes or f.unit is None:
            continue
        for pt in f.points:
            v = pt.get("value")
            if isinstance(v, float) and not math.isfinite(v):  # a float register's NaN: nothing to hold against
                continue
            addr = pt.get("address")
            if not (pt.get("id") and addr is not None and v is not None):
                continue
            key = (f.model, addr)
            if key not in settable:
                settable[key] = _settable(session.registry, f.model, addr)
            if settable[key]:
                last[(f.link, f.unit, pt["id"])] = v
    if session.error:
        raise ReferenceError(f"--params {path}: {session.error}")
    return Reference(path, [(ln, u, pid, v) for (ln, u, pid), v in last.items()])


def _settable(registry, model: str | None, addr: int) -> bool:
    """Is the register a parameter (the map lets the master write it)?  A monitor register (output frequency,
    current: access R) changes with the drive's work: another value later is no changed parameter."""
    dec = registry.decoders.get(model) if registry is not None and model else None
    regmap = getattr(dec, "map", None)
    r = regmap.registers.get(addr) if regmap is not None else None
    return r is None or "W" in (getattr(r, "access", "RW") or "RW")


def load(path: str, spec) -> Reference:
    """The reference at `path` (a regular file: a FIFO, a device or a folder is refused in one line)."""
    try:
        open_regular(path, "a parameter set or capture", ReferenceError).close()
    except ReferenceError as e:
        raise ReferenceError(f"--params {e}") from None
    if path.lower().endswith(".csv") and _looks_like_params(path):
        return load_csv(path)
    try:
        return load_capture(path, spec)
    except (CaptureError, ValueError) as e:
        if not path.lower().endswith(".csv"):
            raise
        why = str(e).removeprefix("--params ")
        raise ReferenceError(f"--params {path}: neither a parameter CSV (a header line with the columns unit, "
                             f"register, value) nor a capture ({why})") from None


def _looks_like_params(path: str) -> bool:
    """A parameter CSV (unit,register,value), not a byte CSV capture."""
    try:
        with open_regular(path, KIND) as fh:
            head = fh.readline(4096).decode("utf-8-sig").lower()
    except (OSError, CaptureError, UnicodeDecodeError):
        return False
    return any(word in head for word in ("unit", "register", "value"))
