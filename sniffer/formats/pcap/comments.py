"""A pcapng packet's comment: what the sniffer knows of a frame and Wireshark's Modbus/RTU dissector does not.

Wireshark decodes the bytes (mbrtu); the comment adds the drive model's register names and values,
the CRC verdict and UART flags, the request/response pair with its latency, and how the time was taken
(per byte, per USB read, per network read), one fact per line:

    rs485-sniffer #41: response u2 a510 fc03, CRC ok
    Output frequency (12-00) = 38.0 Hz
    answers #40, latency 7.621 ms
    time per read: estimated from the read and the baud rate

(#N: the sniffer's frame number, from 0, as in its JSONL and TUI; noise frames are packets too.)
"""

from __future__ import annotations

from sniffer.events import PER_READ
from sniffer.frame import RESPONSE, Frame

TIME_NOTES = {
    "byte": "time per byte: measured",
    "read": "time per read: estimated from the read and the baud rate",
    "net": "time per network read: after the gateway's packing and the network",
    "none": "no time",
}
MAX_POINTS = 24  # a long block write: the first this many, then how many more
MAX_CHARS = 3000


def frame_comment(f: Frame) -> str:
    lines = [_head(f)]
    points = f.points if f.protocol != "noise" else []
    for p in points[:MAX_POINTS]:
        lines.append(_point(p))
    if len(points) > MAX_POINTS:
        lines.append(f"... {len(points) - MAX_POINTS} more registers")
    if f.pair is not None:
        lines.append(_pair(f))
    for a in f.annotations:
        lines.append(f"{a.code} ({a.severity}): {a.detail}")
    lines.append(TIME_NOTES.get(f.time_source, f"time source {f.time_source}"))
    text = "\n".join(lines)
    return text if len(text) <= MAX_CHARS else text[:MAX_CHARS - 3] + "..."


def _head(f: Frame) -> str:
    if f.protocol == "noise":
        return f"rs485-sniffer #{f.index}: noise, {len(f.raw)} bytes ({f.noise_reason})"
    unit = "u?" if f.unit is None else f"u{f.unit}"
    model = f" {f.model}" if f.model else ""
    fc = "" if f.function is None else f" fc{f.function:02d}"
    crc = "CRC ok" if f.crc_ok else "CRC BAD" if f.crc_ok is False else "no CRC"
    link = f" [{f.link}]" if f.link else ""
    summary = f": {f.summary}" if f.summary and not f.points else ""  # the points say it, one a line
    return f"rs485-sniffer #{f.index}: {f.role} {unit}{model}{fc}, {crc}{link}{summary}"


def _pair(f: Frame) -> str:
    if f.role != RESPONSE:
        return f"answered by #{f.pair}"
    if f.latency_ms is not None:
        return f"answers #{f.pair}, latency {f.latency_ms:.3f} ms"
    if f.time_source in PER_READ:
        return f"answers #{f.pair}, no latency (read together with its request)"
    return f"answers #{f.pair}"


def _point(p: dict) -> str:
    name = p.get("name") or f"register {p.get('address')}"
    if len(name) > 60:
        name = name[:57] + "..."
    ident = f" ({p['id']})" if p.get("id") else f" ({p['address']:04X}H)" if isinstance(p.get("address"), int) else ""
    value = str(p.get("text") or p.get("value"))
    if len(value) > 120:
        value = value[:117] + "..."
    unit = f" {p['unit']}" if p.get("unit") and not p.get("text") else ""
    return f"{name}{ident} = {value}{unit}"
