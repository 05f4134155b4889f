"""A register map from Home Assistant's `modbus:` YAML (its sensors: the registers a plant already polls).

    modbus:
      - name: meters
        type: serial
        sensors:
          - name: L1 voltage
            slave: 1                      # or device_address
            address: 0
            input_type: input             # holding (default) | input
            data_type: float32            # int16 (default) uint16 int32 uint32 int64 uint64 float32 float64 string
            swap: word                    # none | byte | word | word_byte
            scale: 1
            unit_of_measurement: V

A file whose sensors name one slave (or none) is one model, its id the file's stem; sensors
of several slaves make one model per slave, `<stem>-u<slave>`.  What the map format cannot
say is kept in the row's note: an `offset` (not applied), `precision` (display only).
A sensor's `input_type` is its row's `table`: an input sensor names input registers (FC04) only,
a holding one holding registers (FC03/06/10), so a meter's input 0000H and holding 0000H keep
their own names.  Other platforms (binary_sensors, switches, climates, ...) are coils or write
targets, not register readings, and are left out.  `!secret` / `!include` values are read as
text (an `!include`d sensors list is not followed: the error says so).

Aliases (`*name`, `<<: *name`) are followed as YAML says, within MAX_EXPANSION nodes more than the
file holds: a few kilobytes of nested aliases ("billion laughs") would otherwise expand to
gigabytes.  The node graph is measured before anything is built from it; past the bound, or for an
alias of itself, the file is refused with one line.
"""

from __future__ import annotations

import os

from ..regtypes import WIDTH, canonical
from ..tables import MapError, RegisterMap, brief, map_from_doc
from .common import model_id_of, parse_number, read_text

MAX_EXPANSION = 100_000  # nodes aliases may add to the file's own (a sensors list merging defaults: a few each)

_TYPES = {"int16": "s16", "uint16": "u16", "int32": "s32", "uint32": "u32", "int64": "s64", "uint64": "u64",
          "float32": "f32", "float64": "f64", "string": "str",
          # before HA 2021.x: int / uint / float with `count` registers
          ("int", 1): "s16", ("int", 2): "s32", ("int", 4): "s64", ("uint", 1): "u16", ("uint", 2): "u32",
          ("uint", 4): "u64", ("float", 2): "f32", ("float", 4): "f64"}
_SWAP = {"none": ("big", "big"), "byte": ("big", "little"), "word": ("little", "big"),
         "word_byte": ("little", "little")}
_SPACES = {"holding": "holding", "input": "input"}


def _loader():
    import yaml

    class Loader(yaml.SafeLoader):
        """Safe YAML that keeps each mapping's line (`__line__`) and reads HA's tags as text."""

    def mapping(loader, node, deep=False):
        d = loader.construct_mapping(node, deep=deep)
        d["__line__"] = node.start_mark.line + 1
        return d

    def tagged(loader, suffix, node):
        if isinstance(node, yaml.ScalarNode):
            return f"!{suffix} {loader.construct_scalar(node)}"
        return f"!{suffix}"

    Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
    Loader.add_multi_constructor("!", tagged)
    return Loader


def _check_expansion(root, path: str) -> None:
    """MapError if following the aliases under `root` would build more than MAX_EXPANSION nodes beyond the
    file's own, or if an alias holds itself (the sizes are counted on the node graph, nothing is built)."""
    size: dict[int, int] = {}  # id(node) -> nodes it stands for, aliases followed
    busy: set[int] = set()
    distinct: set[int] = set()

    def measure(node) -> int:
        key = id(node)
        if key in size:
            return size[key]
        if key in busy:
            raise MapError(f"{path}: line {node.start_mark.line + 1}: an alias refers to the node that holds it "
                           f"(a recursive structure is not a register map)")
        distinct.add(key)
        value = node.value
        if isinstance(value, list):
            busy.add(key)
            n = 1
            for item in value:
                n += sum(measure(x) for x in item) if isinstance(item, tuple) else measure(item)
                if n - len(distinct) > MAX_EXPANSION:
                    raise MapError(f"{path}: line {node.start_mark.line + 1}: its aliases expand to more than "
                                   f"{MAX_EXPANSION} nodes (nested aliases?): not a register map")
            busy.discard(key)
        else:
            n = 1
        size[key] = n
        return n

    total = measure(root)
    if total - len(distinct) > MAX_EXPANSION:
        raise MapError(f"{path}: its aliases expand to more than {MAX_EXPANSION} nodes (nested aliases?): "
                       f"not a register map")


def _hubs(doc, path: str) -> list[dict]:
    if isinstance(doc, dict) and "modbus" in doc:
        doc = doc["modbus"]
    elif isinstance(doc, dict) and "sensors" not in doc:
        doc = None
    if isinstance(doc, dict):
        doc = [doc]
    if not isinstance(doc, list) or not all(isinstance(h, dict) for h in doc):
        raise MapError(f"{path}: not a Home Assistant modbus configuration (expected `modbus:` with a list of hubs)")
    return doc


def load_ha_yaml(path: str, base: str | None = None) -> list[RegisterMap]:
    """The map(s) in the Home Assistant modbus YAML `path` (see the module doc); `base` is not used (HA
    addresses are 0-based register numbers)."""
    import yaml

    text = read_text(path)
    loader = None
    try:
        loader = _loader()(text)  # its reader refuses unprintable characters (a NUL) as it is made
        node = loader.get_single_node()
        if node is not None:
            _check_expansion(node, path)
        doc = loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        what = " ".join(str(getattr(e, "problem", None) or e).split())[:160]
        raise MapError(f"{path}: {where}not valid YAML ({what})") from None
    except RecursionError:
        raise MapError(f"{path}: nested too deeply to be a register map") from None
    finally:
        if loader is not None:
            loader.dispose()
    groups: dict[object, tuple[list[dict], list[str], dict[int, tuple[str, str]]]] = {}
    fname = os.path.basename(path)
    n = 0
    for hub in _hubs(doc, path):
        sensors = hub.get("sensors") or []
        if isinstance(sensors, str):
            raise MapError(f"{path}: line {hub.get('__line__', '?')}: sensors {sensors[:60]!r} is in another file; "
                           f"give that file (with the hub around it)")
        if not isinstance(sensors, list):
            raise MapError(f"{path}: line {hub.get('__line__', '?')}: sensors must be a list")
        for s in sensors:
            if not isinstance(s, dict):
                raise MapError(f"{path}: line {hub.get('__line__', '?')}: a sensor must be a mapping, "
                               f"not {brief(s, 40)}")
            where = f"line {s.get('__line__', '?')}"
            try:
                row, slave, space = _row(s, fname, where)
            except ValueError as e:
                raise MapError(f"{path}: {where}: {e}") from None
            rows, places, _spaces = groups.setdefault(slave, ([], [], {}))
            row["table"] = space  # an input sensor names input registers only (a meter has both at 0000H)
            rows.append(row)
            places.append(where)
            n += 1
    if not n:
        raise MapError(f"{path}: no modbus sensors in the file")
    stem = model_id_of(path)
    out = []
    for slave, (rows, places, _spaces) in groups.items():
        mid = stem if len(groups) == 1 or slave is None else f"{stem}-u{slave}"
        model = {"id": mid, "manual": fname}
        if slave is not None:
            model["name"] = f"{stem} slave {slave}"
        out.append(map_from_doc({"model": model, "registers": rows}, path, places))
    return out


def _row(s: dict, fname: str, where: str) -> tuple[dict, object, str]:
    name = s.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ValueError("a sensor needs a name")
    addr = s.get("address")
    if isinstance(addr, bool) or not isinstance(addr, int) or not 0 <= addr <= 0xFFFF:
        raise ValueError(f"address {brief(addr, 40)} must be a register number 0..65535")
    space = str(s.get("input_type", "holding")).strip().lower()
    if space not in _SPACES:
        raise ValueError(f"input_type {space[:40]!r}: only holding and input registers go into a register map")
    dt = str(s.get("data_type", "int16")).strip().lower()
    count = s.get("count")
    typ = _TYPES.get(dt) or _TYPES.get((dt, count))
    if typ is None:
        if dt == "custom":
            raise ValueError("data_type custom (a struct format) has no register-map type; split it into sensors")
        raise ValueError(f"data_type {dt[:40]!r} (one of int16, uint16, int32, uint32, int64, uint64, float32, "
                         f"float64, string)")
    row: dict = {"addr": addr, "name": name.strip(), "type": typ,
                 "access": "R" if space == "input" else "RW"}
    if typ == "str":
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ValueError("a string sensor needs count = its length in registers")
        row["words"] = count
    swap = str(s.get("swap", "none")).strip().lower()
    if swap not in _SWAP:
        raise ValueError(f"swap {swap[:40]!r} (one of none, byte, word, word_byte)")
    wo, bo = _SWAP[swap]
    if wo != "big":
        row["word_order"] = wo
    if bo != "big":
        row["byte_order"] = bo
    if "scale" in s:
        row["scale"] = float(parse_number(s["scale"], "scale"))
    if s.get("unit_of_measurement"):
        row["unit"] = str(s["unit_of_measurement"])
    notes = []
    if s.get("offset"):
        notes.append(f"Home Assistant adds offset {s['offset']} (not applied here)")
    if s.get("precision") is not None:
        notes.append(f"shown with {s['precision']} decimals in Home Assistant")
    if notes:
        row["note"] = "; ".join(notes)
    more = s.get("slave_count", s.get("virtual_count"))
    if more:
        if isinstance(more, bool) or not isinstance(more, int) or more < 0:
            raise ValueError(f"slave_count {brief(more, 40)} must be a whole number")
        row["count"] = more + 1
        row["stride"] = WIDTH.get(canonical(typ)) or row["words"]
    row["section"] = f"{fname} {where} ({space})"
    slave = s.get("slave", s.get("device_address"))
    if slave is not None and (isinstance(slave, bool) or not isinstance(slave, int) or not 0 <= slave <= 255):
        raise ValueError(f"slave {brief(slave, 40)} must be a unit address 0..255")
    return row, slave, space
