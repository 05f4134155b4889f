"""Framing: the line's bytes and silences into frames, CRC-16 and LRC checked (sans-I/O).

    linebuf.py      LineBuffer: bytes, their times, the silences; what every framer reads
    crc_rules.py    rules A, B1..B5 over a line of CRC-16 checked frames (RTU and PD RTU share them)
    hexline.py      ':' hex pairs CR LF (Modbus ASCII and PD ASCII share it)
    rtu.py          Modbus RTU          ascii.py   Modbus ASCII          pd.py   PD-series RTU and ASCII
    packet.py       PacketFramer: a frame that says its length and ends in a check (protocol plugins)
    rtu_lengths.py  the lengths a function code and role imply
    crc.py          CRC-16/MODBUS and LRC

A protocol's framer is named by its entry in sniffer.protocols; framing imports nothing above it
(pyproject.toml's import contracts).
"""

from sniffer import face

_EXPORTS = {
    "LineBuffer": "sniffer.framing.linebuf",
    "PacketFramer": "sniffer.framing.packet",
    "RtuFramer": "sniffer.framing.rtu",
    "AsciiFramer": "sniffer.framing.ascii",
    "PdRtuFramer": "sniffer.framing.pd",
    "PdAsciiFramer": "sniffer.framing.pd",
    "crc_ok": "sniffer.framing.crc",
    "crc_bytes": "sniffer.framing.crc",
    "crc16_modbus": "sniffer.framing.crc",
    "lrc": "sniffer.framing.crc",
}
__all__ = sorted(_EXPORTS)
__getattr__ = face(__name__, _EXPORTS)
