"""rs485-sniffer plugin: the ACME Link protocol (its framer and decoder) and the ACME X2's register map.

ACME Link, from the (imaginary) ACME drive manual, chapter 9:

    7E | unit | cmd | len | data (len bytes) | CRC-16/CCITT (2 bytes, high first)   master -> drive
    7F | unit | cmd | len | data (len bytes) | CRC-16/CCITT                        drive -> master

The CRC (polynomial 1021H, initial FFFFH, no reflection) covers unit .. data.  Commands: 01H read registers
(data: address high, low, count; the answer repeats them, then 2 bytes a value), 02H write one register
(data: address high, low, value high, low; the answer echoes it).  A refused command is answered with
cmd | 80H and one error byte.
"""

from importlib.resources import files

from sniffer.plugins import ProtocolPlugin

from acme_plugin.decoder import AcmeDecoder
from acme_plugin.framing import AcmeFramer

PROTOCOL = ProtocolPlugin(name="acme-link", framer=AcmeFramer, decoder=AcmeDecoder,
                          tables={0x01: "holding", 0x02: "holding"})
X2_MAP = files("acme_plugin") / "acme-x2.toml"  # a Modbus device: a register map, no Python
