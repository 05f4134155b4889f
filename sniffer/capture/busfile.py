"""Bus file: the serial settings, unit -> model map and timeouts of one line, in TOML.

    [serial]
    baud = 19200        # integer, 50..4000000
    parity = "E"        # N, E or O
    stopbits = 1        # 1 or 2
    databits = 8        # 8 or 7 (optional; Modbus ASCII lines often run 7E1)
    protocol = "modbus-rtu"   # one of sniffer.protocols.NAMES (optional)

    [units]          # unit (0..255) = model id
    1 = "a510"
    2 = "tds-v8"

    [timeouts_ms]    # optional, per unit: a finite number >= 0
    1 = 250

    [parameters]     # optional, per unit: settings the bus may never show, by the manual's id,
    2 = { "Cn-02" = 60 }   # in the register's unit (or "60 Hz"): the unit's values are scaled by
                           # them from the first frame (docs/values.md); the unit needs its model

    broadcast = "tds-v8"   # optional, before the first table: the model whose manual
                           # rules unit 0 (broadcast) frames; same as [units] 0 = "tds-v8".
                           # Without it a broadcast takes the model all units share, if one.

Several links on one timeline (`sniffer live --bus plant.toml`): one [[links]]
table per link, each with its name, its port (or `tap`, the two receive-only
adapters of a 4-wire link: the master's pair first), and its own settings and
units; [serial] and [units] above them are every link's defaults.

    [[links]]
    name = "drives"
    port = "/dev/ttyUSB0"
    baud = 19200
    parity = "E"
    units = { 1 = "a510", 2 = "tds-v8" }
    timeouts_ms = { 1 = 250 }
    parameters = { 2 = { "Cn-02" = 50 } }

    [[links]]
    name = "pumps"
    tap = ["/dev/ttyUSB1", "/dev/ttyUSB2"]   # master's pair, slaves' pair
    baud = 9600
    protocol = "pd-rtu"

`format_bus_file` writes one (`sniffer detect --write-bus`), `format_links` one of [[links]]
(`sniffer detect P1 P2 --write-bus`), `load_bus_file`
reads it.  Every field is checked before use; a bad one is BusFileError("<path>: <what>"),
one line.  Unknown tables and keys are errors too, naming what was found: a
typo such as `[unit]` or `buad = 9600` would otherwise be silently ignored
and the capture decoded with the wrong settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from decoders.tomlfile import read_toml

BAUD_RANGE = (50, 4_000_000)
TABLES = ("serial", "units", "timeouts_ms", "parameters", "links")
TOP_KEYS = ("broadcast",)
SERIAL_KEYS = ("baud", "parity", "stopbits", "databits", "protocol")
LINK_KEYS = ("name", "port", "tap", *SERIAL_KEYS, "units", "timeouts_ms", "parameters")
MAX_TIMEOUT_MS = 86_400_000.0  # a day: anything longer is a typo


class BusFileError(ValueError):
    pass


@dataclass
class BusFile:
    baud: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    protocol: str | None = None
    databits: int | None = None
    devices: dict[int, str] = field(default_factory=dict)
    timeouts_ms: dict[int, float] = field(default_factory=dict)
    params: dict[int, dict[str, float | str]] = field(default_factory=dict)  # [parameters]: unit -> id -> value
    path: str = ""
    links: list[BusFile] = field(default_factory=list)  # [[links]]: each a BusFile with a name and ports
    name: str = ""
    ports: tuple[str, ...] = ()
    tap: bool = False


def _show(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:60] + "..."


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _unit(path: str, table: str, key: str) -> int:
    k = key.strip()
    if not (k.isascii() and k.isdigit() and len(k) <= 3 and int(k) <= 255):
        raise BusFileError(f"{path}: [{table}] key {_show(key)} is not a unit number 0..255")
    return int(k)


def _table(path: str, doc: dict, name: str) -> dict:
    t = doc.get(name, {})
    if not isinstance(t, dict):
        raise BusFileError(f"{path}: {name} must be a table [{name}], not {_show(t)}")
    return t


def _serial(path: str, serial: dict, bus: BusFile, where: str = "[serial]") -> None:
    from sniffer.protocols import known

    unknown = sorted(set(serial) - set(SERIAL_KEYS))
    if unknown:
        raise BusFileError(f"{path}: {where} unknown keys {_show(unknown)} (known: {', '.join(SERIAL_KEYS)})")
    baud = serial.get("baud")
    if baud is not None and (not _is_int(baud) or not BAUD_RANGE[0] <= baud <= BAUD_RANGE[1]):
        raise BusFileError(f"{path}: {where} baud must be an integer {BAUD_RANGE[0]}..{BAUD_RANGE[1]}, "
                           f"not {_show(baud)}")
    parity = serial.get("parity")
    if parity is not None:
        if not isinstance(parity, str) or parity.strip().upper() not in ("N", "E", "O"):
            raise BusFileError(f"{path}: {where} parity must be \"N\", \"E\" or \"O\", not {_show(parity)}")
        parity = parity.strip().upper()
    stopbits = serial.get("stopbits")
    if stopbits is not None and (not _is_int(stopbits) or stopbits not in (1, 2)):
        raise BusFileError(f"{path}: {where} stopbits must be 1 or 2, not {_show(stopbits)}")
    databits = serial.get("databits")
    if databits is not None and (not _is_int(databits) or databits not in (7, 8)):
        raise BusFileError(f"{path}: {where} databits must be 7 or 8, not {_show(databits)}")
    protocol = serial.get("protocol")
    if protocol is not None and (not isinstance(protocol, str) or protocol not in known()):
        raise BusFileError(f"{path}: {where} protocol {_show(protocol)} is not one of {', '.join(known())}")
    bus.baud, bus.parity, bus.stopbits, bus.databits, bus.protocol = baud, parity, stopbits, databits, protocol


def load_bus_file(path: str) -> BusFile:
    """The bus file at `path`, every field checked; BusFileError (one line) if any is wrong."""
    doc = read_toml(path, BusFileError)
    unknown = sorted(set(doc) - set(TABLES) - set(TOP_KEYS))
    if unknown:
        raise BusFileError(f"{path}: unknown tables or keys {_show(unknown)} "
                           f"(known: {', '.join(TABLES + TOP_KEYS)})")
    bus = BusFile(path=path)
    _serial(path, _table(path, doc, "serial"), bus)
    _units(path, doc, bus, "")
    if "broadcast" in doc:
        model = doc["broadcast"]
        if not isinstance(model, str) or not model.strip():
            raise BusFileError(f"{path}: broadcast must be a model id string (e.g. \"tds-v8\"), not {_show(model)}")
        if bus.devices.get(0, model.strip()) != model.strip():
            raise BusFileError(f"{path}: broadcast = {_show(model)} but [units] 0 = {_show(bus.devices[0])}")
        bus.devices[0] = model.strip()
    links = doc.get("links", [])
    if not isinstance(links, list) or not all(isinstance(x, dict) for x in links):
        raise BusFileError(f"{path}: links must be tables [[links]], not {_show(links)}")
    bus.links = [_link(path, i, x) for i, x in enumerate(links)]
    names = [b.name for b in bus.links]
    ports = [p for b in bus.links for p in b.ports]
    for what, seen in (("name", names), ("port", ports)):
        twice = sorted({x for x in seen if seen.count(x) > 1})
        if twice:
            raise BusFileError(f"{path}: [[links]] {what} {_show(twice[0])} given twice")
    return bus


def _link(path: str, i: int, t: dict) -> BusFile:
    """One [[links]] table: a name, a port or a tap, and the link's own settings and units."""
    where = f"[[links]] #{i + 1}"
    unknown = sorted(set(t) - set(LINK_KEYS))
    if unknown:
        raise BusFileError(f"{path}: {where} unknown keys {_show(unknown)} (known: {', '.join(LINK_KEYS)})")
    name = t.get("name")
    if not isinstance(name, str) or not name.strip() or any(c.isspace() or c in ",:\"" for c in name.strip()):
        raise BusFileError(f"{path}: {where} needs a name: a word (e.g. name = \"drives\"), not {_show(name)}")
    where = f"[[links]] {name.strip()}"
    port, tap = t.get("port"), t.get("tap")
    if (port is None) == (tap is None):
        raise BusFileError(f"{path}: {where} needs a port = \"/dev/...\" or a tap = [master's port, slaves' port]")
    if port is not None and (not isinstance(port, str) or not port.strip()):
        raise BusFileError(f"{path}: {where} port must be a device path, not {_show(port)}")
    if tap is not None and (not isinstance(tap, list) or len(tap) != 2
                            or not all(isinstance(p, str) and p.strip() for p in tap)):
        raise BusFileError(f"{path}: {where} tap must be two device paths [master's pair, slaves' pair], "
                           f"not {_show(tap)}")
    link = BusFile(path=path, name=name.strip(), ports=(port.strip(),) if port is not None else
                   tuple(p.strip() for p in tap), tap=tap is not None)
    _serial(path, {k: v for k, v in t.items() if k in SERIAL_KEYS}, link, where)
    _units(path, t, link, f"{where} ")
    return link


def _units(path: str, doc: dict, bus: BusFile, where: str) -> None:
    """[units] and [timeouts_ms] of the file, or of one link (`where` names it)."""
    for key, model in _table(path, doc, "units").items():
        unit = _unit(path, "units", key)
        if not isinstance(model, str) or not model.strip():
            raise BusFileError(f"{path}: {where}[units] {key} must be a model id string (e.g. \"a510\"), "
                               f"not {_show(model)}")
        bus.devices[unit] = model.strip()
    for key, ms in _table(path, doc, "timeouts_ms").items():
        unit = _unit(path, "timeouts_ms", key)
        ok = (_is_int(ms) or isinstance(ms, float)) and math.isfinite(ms) and 0 <= ms <= MAX_TIMEOUT_MS
        if not ok:
            raise BusFileError(f"{path}: {where}[timeouts_ms] {key} must be a number of milliseconds "
                               f"0..{MAX_TIMEOUT_MS:.0f}, not {_show(ms)}")
        bus.timeouts_ms[unit] = float(ms)
    for key, values in _table(path, doc, "parameters").items():
        unit = _unit(path, "parameters", key)
        if not isinstance(values, dict) or not values:
            raise BusFileError(f"{path}: {where}[parameters] {key} must be a table of the manual's ids and values "
                               f"(e.g. {key} = {{ \"Cn-02\" = 60 }}), not {_show(values)}")
        for pid, v in values.items():
            ok = (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)) or (
                isinstance(v, str) and v.strip())
            if not pid.strip() or not ok:
                raise BusFileError(f"{path}: {where}[parameters] {key}.{_show(pid)} must be a number in the "
                                   f"register's unit (or a string such as \"60 Hz\"), not {_show(v)}")
        bus.params[unit] = {pid.strip(): v for pid, v in values.items()}


def format_bus_file(bus: BusFile, comments: list[str] = (), trailer: list[str] = ()) -> str:
    """The text of a bus file saying what `bus` says (comment lines before and after), as load_bus_file
    reads it back."""
    out = [f"# {c}" if c else "#" for c in comments]
    serial = [(k, getattr(bus, k)) for k in ("baud", "parity", "stopbits", "databits", "protocol")]
    if any(v is not None for _, v in serial):
        out += ["[serial]"] + [f"{k} = {_toml(v)}" for k, v in serial if v is not None]
    for title, table in (("units", bus.devices), ("timeouts_ms", bus.timeouts_ms)):
        if table:
            out += ["", f"[{title}]"] + [f"{unit} = {_toml(v)}" for unit, v in sorted(table.items())]
    if bus.params:
        out += ["", "[parameters]"] + [
            f"{unit} = {{ {', '.join(f'{_toml(k)} = {_toml(v)}' for k, v in values.items())} }}"
            for unit, values in sorted(bus.params.items())]
    if trailer:
        out += [""] + [f"# {c}" if c else "#" for c in trailer]
    return "\n".join(out) + "\n"


def format_links(links: list[BusFile], comments: list[str] = (), notes: list[list[str]] = ()) -> str:
    """The text of a bus file of [[links]] tables (each BusFile one link: its name, port or tap, settings and
    units), comment lines before them and after each link's table (`notes[i]`), as load_bus_file reads it back."""
    out = [f"# {c}" if c else "#" for c in comments]
    for i, link in enumerate(links):
        out += ["", "[[links]]", f"name = {_toml(link.name)}"]
        if link.tap:
            out.append(f"tap = [{', '.join(_toml(p) for p in link.ports)}]")
        else:
            out.append(f"port = {_toml(link.ports[0])}")
        out += [f"{k} = {_toml(getattr(link, k))}" for k in SERIAL_KEYS if getattr(link, k) is not None]
        for title, table in (("units", link.devices), ("timeouts_ms", link.timeouts_ms)):
            if table:
                out.append(f"{title} = {{ {', '.join(f'{u} = {_toml(v)}' for u, v in sorted(table.items()))} }}")
        out += [f"# {c}" if c else "#" for c in (notes[i] if i < len(notes) else ())]
    return "\n".join(out).lstrip("\n") + "\n"


def _toml(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(v)
