"""The `rs485_sniffer.protocols` group: line protocols from other packages, a framer and its decoder.

An entry gives a ProtocolPlugin (or an object with the same attributes, or a zero-argument callable
returning one): `name` (what --protocol and a bus file's `protocol` take), `framer` (a class made with a
line's sniffer.line.LineSettings that splits bytes into Frames: sniffer.framing.PacketFramer does the work
for a framing with a length field and a check), `decoder` (a decoder, as in the models group, or a factory
of one: it is the protocol's default model and takes --device ids as any model), and optionally `tables`
({function: "holding" | "input" | "coil" | "discrete"}: which register table a function's addresses name)
and `text` (True for an ASCII framing whose frames hold characters).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

GROUP = "rs485_sniffer.protocols"
_NAME = re.compile(r"^[a-z0-9][a-z0-9-]{0,31}$")
BUILT_IN = ("modbus-rtu", "modbus-ascii", "pd-rtu", "pd-ascii", "noise", "line")  # names no plugin takes
_TABLES = ("coil", "discrete", "holding", "input")


@dataclass(frozen=True)
class ProtocolPlugin:
    name: str
    framer: type
    decoder: object
    tables: Mapping[int, str] = field(default_factory=dict)
    text: bool = False


def check(name: str, obj) -> ProtocolPlugin:
    """The ProtocolPlugin of an entry's object (its decoder made and checked); TypeError / ValueError."""
    from sniffer.plugins.models import check_decoder

    if not isinstance(obj, ProtocolPlugin) and callable(obj) and not hasattr(obj, "framer"):
        obj = obj()
    pname = getattr(obj, "name", None)
    if not isinstance(pname, str) or not _NAME.match(pname):
        raise ValueError(f"name must be lower-case letters, digits and '-', not {str(pname)[:40]!r}")
    if pname in BUILT_IN:
        raise ValueError(f"name {pname!r} is a built-in protocol's")
    framer = getattr(obj, "framer", None)
    if not isinstance(framer, type) or not all(callable(getattr(framer, m, None)) for m in ("feed", "tick", "flush")):
        raise TypeError("framer must be a class with feed, tick and flush (subclass sniffer.framing.PacketFramer)")
    if getattr(framer, "protocol", None) != pname:
        raise ValueError(f"its framer's protocol is {getattr(framer, 'protocol', None)!r}, not {pname!r}")
    decoder = getattr(obj, "decoder", None)
    if isinstance(decoder, type) or (callable(decoder) and not hasattr(decoder, "decode")):
        decoder = decoder()  # a class or a factory
    check_decoder(decoder, "decoder: ")
    tables = dict(getattr(obj, "tables", None) or {})
    if not all(isinstance(k, int) and 0 <= k <= 255 and v in _TABLES for k, v in tables.items()):
        raise ValueError(f"tables must map function codes 0..255 to one of {', '.join(_TABLES)}")
    return ProtocolPlugin(pname, framer, decoder, tables, bool(getattr(obj, "text", False)))


def protocol_plugins():
    """The protocol plugins that loaded and passed (Plugin.obj: a ProtocolPlugin); two of one name: the first."""
    from sniffer.plugins.entry import load, warn

    out, names = [], set()
    for p in load(GROUP, check):
        if p.obj.name in names:
            warn(GROUP, p.name, p.value, p.dist, f"protocol {p.obj.name!r} is another plugin's already")
            continue
        names.add(p.obj.name)
        out.append(p)
    return tuple(out)


def protocol_names() -> tuple[str, ...]:
    """The names the protocol plugins declare, without loading them (the entry points' names): for --protocol's
    choices and completion.  A plugin's entry point is named as its protocol."""
    from sniffer.plugins.entry import entries

    return tuple(dict.fromkeys(ep.name for ep in entries(GROUP) if _NAME.match(ep.name) and ep.name not in BUILT_IN))
