"""The line protocols: one entry per protocol, every fact about it in one place.

    protocol = get("modbus-ascii")
    framer = protocol.framer(line)           # its framer class, on these line settings
    protocol.default_model                   # the model for units without a --device entry
    protocol.codes                           # the annotation codes its framer may emit
    protocol.table_of(0x03)                  # "holding": the register table a function reads/writes
    protocol.raw_span(2, 4, len(raw))        # ADU bytes [2, 4) as a span of the wire bytes

A new protocol is a framer class (a `LineBuffer` subclass that declares its
`codes`) and one `Protocol` entry below; nothing else lists protocols.  Protocols of
other packages (sniffer.plugins, the `rs485_sniffer.protocols` entry points) join them
in `known()`: `get`, `of_frame`, `names` and `all_codes` read that.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from sniffer.codes import Code
from sniffer.line import LineSettings, SettingsError

# the four tables of the Modbus data model (the register shadow keeps one dict per table)
COIL, DISCRETE, HOLDING, INPUT = "coil", "discrete", "holding", "input"
TABLES = (COIL, DISCRETE, HOLDING, INPUT)

# function code -> the table its addresses live in (Modbus application protocol 6.1-6.17)
MODBUS_TABLES: Mapping[int, str] = MappingProxyType({
    0x01: COIL, 0x02: DISCRETE, 0x03: HOLDING, 0x04: INPUT, 0x05: COIL, 0x06: HOLDING,
    0x0F: COIL, 0x10: HOLDING, 0x16: HOLDING, 0x17: HOLDING,
})
# the most registers (or bits) one frame of a function can name (Modbus application protocol 6.1-6.17; 17H:
# its read part), and the end of every table: a quantity beyond, or registers past 65535, name no registers
MODBUS_MAX_QUANTITY: Mapping[int, int] = MappingProxyType({
    0x01: 2000, 0x02: 2000, 0x03: 125, 0x04: 125, 0x0F: 1968, 0x10: 123, 0x17: 125,
})
TABLE_END = 0x10000


def modbus_range_ok(fc: int, a: int, q: int) -> bool:
    """Can `q` registers (or bits) from `a` be what a frame of function `fc` names: a quantity the function
    carries, every address below 65536?  A frame whose fields say otherwise (CRC-bad junk, a device's bug)
    is summarised, filtered and exported without a register range."""
    return 1 <= q <= MODBUS_MAX_QUANTITY.get(fc, TABLE_END) and 0 <= a and a + q <= TABLE_END


# PD-series: 01H/02H read/write a parameter (kept as holding), 04H reads a status value (input)
PD_TABLES: Mapping[int, str] = MappingProxyType({0x01: HOLDING, 0x02: HOLDING, 0x04: INPUT})


@dataclass(frozen=True)
class Protocol:
    name: str
    family: str  # "modbus" or "pd": which request/response rules apply
    text: bool  # ASCII on the wire: raw holds characters, adu the binary bytes
    default_model: str
    tables: Mapping[int, str]
    _framer: str | type  # "module:Class", imported when first used (a plugin's: its class)

    @property
    def framer_class(self):
        import importlib

        if not isinstance(self._framer, str):
            return self._framer
        module, _, cls = self._framer.partition(":")
        return getattr(importlib.import_module(module, __package__), cls)

    def framer(self, line: LineSettings):
        return self.framer_class(line)

    @property
    def codes(self) -> tuple[Code, ...]:
        return tuple(self.framer_class.codes)

    def table_of(self, function: int | None) -> str | None:
        """The register table a function code's addresses belong to (exception bit ignored), or None."""
        if function is None:
            return None
        return self.tables.get(function & 0x7F)

    def adu_of(self, raw: bytes) -> bytes:
        """A frame's ADU (unit + PDU, binary) back from its wire bytes, as its framer set `Frame.adu`: RTU
        framings end in a 2-byte CRC; ASCII is ':' + hex (ADU + LRC) + CRLF.  b"" where it does not read
        (a frame rebuilt from its record, which keeps the raw bytes only)."""
        if not self.text:
            return raw[:-2]
        try:
            return bytes.fromhex(raw[1:].split(b"\r")[0].decode("ascii"))[:-1]
        except ValueError:
            return b""

    def raw_span(self, start: int, end: int, size: int) -> tuple[int, int]:
        """ADU bytes [start, end) as a span of a frame's `size` wire bytes (never empty).

        Binary framings put the ADU first in the frame: the span is the same.
        ASCII puts byte i at characters 1 + 2i and 2 + 2i (after the ':').
        """
        if not self.text:
            return start, end
        s = min(1 + 2 * start, size - 1)
        return s, max(s + 1, min(1 + 2 * end, size))


PROTOCOLS: Mapping[str, Protocol] = MappingProxyType({p.name: p for p in (
    Protocol("modbus-rtu", "modbus", False, "generic", MODBUS_TABLES, "sniffer.framing.rtu:RtuFramer"),
    Protocol("modbus-ascii", "modbus", True, "generic", MODBUS_TABLES, "sniffer.framing.ascii:AsciiFramer"),
    Protocol("pd-rtu", "pd", False, "pd-series", PD_TABLES, "sniffer.framing.pd:PdRtuFramer"),
    Protocol("pd-ascii", "pd", True, "pd-series", PD_TABLES, "sniffer.framing.pd:PdAsciiFramer"),
)})
NAMES: tuple[str, ...] = tuple(PROTOCOLS)
DEFAULT = "modbus-rtu"


_known: Mapping[str, Protocol] | None = None


def known() -> Mapping[str, Protocol]:
    """The built-in protocols and those of the installed plugins (loaded once per process, when first asked:
    a plugin that fails is one warning line and is left out)."""
    global _known
    if _known is None:
        from sniffer.plugins.protocols import protocol_plugins

        found = dict(PROTOCOLS)
        for plugin in protocol_plugins():
            pp = plugin.obj
            found[pp.name] = Protocol(pp.name, pp.name, pp.text, pp.decoder.model, MappingProxyType(dict(pp.tables)),
                                      pp.framer)
        _known = MappingProxyType(found)
    return _known


def names() -> tuple[str, ...]:
    """--protocol's choices: the built-in names, then the plugins' (their entry points' names: none is loaded)."""
    from sniffer.plugins.protocols import protocol_names

    return tuple(dict.fromkeys((*NAMES, *protocol_names())))


def get(name: str) -> Protocol:
    """The protocol named `name`, or SettingsError naming the ones there are."""
    p = (PROTOCOLS.get(name) or known().get(name)) if isinstance(name, str) else None
    if p is None:
        from sniffer.stderr import did_you_mean

        raise SettingsError(f"protocol {str(name)[:60]!r} is not one of {', '.join(known())}"
                            f"{did_you_mean(name, known())}")
    return p


def of_frame(protocol: str) -> Protocol | None:
    """The entry for a frame's `protocol` field (None for noise)."""
    p = PROTOCOLS.get(protocol)
    if p is None and protocol != "noise":
        p = known().get(protocol)
    return p


def all_codes() -> tuple[Code, ...]:
    """Every code the framers of all protocols may emit (for the code book)."""
    seen: dict[str, Code] = {}
    for p in known().values():
        for c in p.codes:
            seen.setdefault(c.code, c)
    return tuple(seen.values())
