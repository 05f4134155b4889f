"""Frame -> JSON record: the JSONL contract other tools and tests depend on.

One object per frame with at least: t, raw, protocol, unit, function, role,
crc_ok, exception, model, points, annotations, latency_ms, pair.  The same
record is the MCAP `/frames` message, described by FRAME_SCHEMA.  Fields are
only ever added, never renamed.

| `points` | `[{name, address, raw, value, unit, span, ...}]`; `span` = `[start, end)` of the value's bytes in `raw` |
| `writes` | `[[table, start, [raw, ...]], ...]`: what the frame wrote into its unit's register shadow |
| `link` | the link's name, in a capture of several links only (`sniffer live P1 P2`, `--tap`, `[[links]]`) |
| `de_on_ns`, `de_off_ns` | logic capture with `--de` only: driver-enable turn-on/-off times (driver_enable.py) |

A point of a value of several registers (u32, f32, str ...) adds `words` (its registers as on
the wire); one register of such a value without the others adds `part` ([index, of]); see
docs/register-map-format.md, "Types".

`writes` is exactly what the decoder put into the unit's register shadow when
it decoded this frame (table: "holding", "input", "coil" or "discrete"; raw
values of consecutive addresses from `start`): a CRC-good read response's
values, a write once its response confirms it (on the response), a broadcast
write at once; never anything from a CRC-bad frame or an exception.  Applying
every frame's `writes` in order rebuilds the decoders' shadow.
"""

from __future__ import annotations

import msgspec

from sniffer.codes import Annotation
from sniffer.events import TIME_SOURCES
from sniffer.frame import Frame
from sniffer.protocols import NAMES, TABLES, of_frame


class _Record(msgspec.Struct, gc=False, omit_defaults=True):
    """The frame record's keys, in order: built positionally and encoded by msgspec in one C call.

    Half the cost of building a dict and encoding it with orjson (measured with valgrind on the
    bench mixes); the bytes are the same but for exponents (msgspec writes 1e16, orjson 1e+16).
    """

    index: int
    t: float
    t_end: float
    raw: str
    protocol: str
    unit: int | None
    function: int | None
    role: str
    crc_ok: bool | None
    crc_expected: str | None
    exception: dict | None
    model: str | None
    points: list | msgspec.Raw
    writes: list
    annotations: list
    latency_ms: float | None  # microsecond resolution (the pairer rounds it)
    pair: int | None
    summary: str
    time_source: str
    channel: str
    noise_reason: str | None
    link: str = ""  # written only in a capture of several links: a one-line record is as it was
    de_on_ns: int | None = None  # written only when known (a logic capture's --de: sniffer.sources.driver_enable)
    de_off_ns: int | None = None


_encode = msgspec.json.Encoder().encode
_decode = msgspec.json.Decoder().decode


def _record(f: Frame, t0_ns: int, points) -> _Record:
    ce = f.crc_expected
    return _Record(
        f.index, (f.t_ns - t0_ns) / 1e9, (f.t_end_ns - t0_ns) / 1e9, f.raw.hex(), f.protocol, f.unit,
        f.function, f.role, f.crc_ok, None if ce is None else f"{ce:04x}", f.exception, f.model, points,
        f.writes, [a.to_dict() for a in f.annotations] if f.annotations else [], f.latency_ms, f.pair,
        f.summary, f.time_source, f.channel, f.noise_reason, f.link, f.de_on_ns, f.de_off_ns,
    )


def frame_record(f: Frame, t0_ns: int) -> dict:
    """The frame as the record's dict (points as dicts)."""
    d = msgspec.structs.asdict(_record(f, t0_ns, f.points))
    for key in ("link", "de_on_ns", "de_off_ns"):
        if d[key] in ("", None):
            del d[key]  # as the JSON has it
    return d


def frame_json(f: Frame, t0_ns: int) -> bytes:
    """The JSON of frame_record(f, t0_ns), encoded once per frame for all the sinks that write it.

    A frame is final when the sinks see it (decoded, paired), so the JSONL
    stream, the MCAP `/frames` channel and the viewers' socket share one encoding.
    """
    enc = f.encoded
    if enc is not None and enc[0] == t0_ns:
        return enc[1]
    pts = f._points  # a decoder's compact block is written as JSON without becoming dicts
    if type(pts) is not list:
        pts = msgspec.Raw(pts.json())
    data = _encode(_record(f, t0_ns, pts))
    f.encoded = (t0_ns, data)
    return data


def dumps(record: dict) -> bytes:
    return _encode(record)


def loads(data: bytes | str) -> dict:
    """JSON -> Python; malformed JSON raises ValueError (msgspec.DecodeError)."""
    return _decode(data)


_NULLABLE_INT = {"type": ["integer", "null"]}
_NULLABLE_NUM = {"type": ["number", "null"]}

FRAME_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sniffer.Frame",
    "description": "One frame seen on the RS-485 line, decoded",
    "type": "object",
    "properties": {
        "index": {"type": "integer", "description": "frame number in the capture"},
        "t": {"type": "number", "description": "seconds from capture start (first byte)"},
        "t_end": {"type": "number", "description": "seconds from capture start (end of last byte)"},
        "raw": {"type": "string", "description": "frame bytes, hex"},
        "protocol": {"type": "string", "enum": [*NAMES, "noise"]},
        "unit": _NULLABLE_INT,
        "function": _NULLABLE_INT,
        "role": {"type": "string", "enum": ["request", "response", "unknown", "noise"]},
        "crc_ok": {"type": ["boolean", "null"]},
        "crc_expected": {"type": ["string", "null"]},
        "exception": {
            "type": ["object", "null"],
            "properties": {"code": {"type": "integer"}, "name": {"type": "string"}},
        },
        "model": {"type": ["string", "null"]},
        "points": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "name": {"type": "string"},
                    "address": _NULLABLE_INT,
                    "raw": {},
                    "value": {},
                    "unit": {"type": ["string", "null"]},
                    "span": {"type": "array", "items": {"type": "integer"}, "minItems": 2, "maxItems": 2,
                             "description": "[start, end): the value's bytes in raw (wire bytes, ASCII "
                                            "characters for modbus-ascii / pd-ascii)"},
                },
            },
        },
        "writes": {
            "type": "array",
            "description": "what decoding this frame wrote into its unit's register shadow, in order: "
                           "[table, start address, [raw values of consecutive addresses]] runs "
                           "(a read response's values, a write confirmed by this response, a broadcast "
                           "write; none from a CRC-bad frame or an exception)",
            "items": {
                "type": "array",
                "prefixItems": [
                    {"type": "string", "enum": list(TABLES)},
                    {"type": "integer"},
                    {"type": "array", "items": {"type": "integer"}},
                ],
                "minItems": 3,
                "maxItems": 3,
            },
        },
        "annotations": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "code": {"type": "string"},
                    "severity": {"type": "string", "enum": ["info", "warning", "error"]},
                    "detail": {"type": "string"},
                    "span": {"type": "array", "items": {"type": "integer"}},
                },
            },
        },
        "latency_ms": _NULLABLE_NUM,
        "pair": _NULLABLE_INT,
        "summary": {"type": "string"},
        "time_source": {"type": "string", "enum": list(TIME_SOURCES)},
        "channel": {"type": "string"},
        "noise_reason": {"type": ["string", "null"]},
        "link": {"type": "string", "description": "the link's name; only in a capture of several links"},
        "de_on_ns": {"type": "integer", "description": "logic capture with --de: the slave's driver-enable rise "
                     "minus the start of the frame's first start bit (ns; > 0: enabled late); only when known"},
        "de_off_ns": {"type": "integer", "description": "logic capture with --de: the driver-enable fall minus "
                      "the end of the frame's last stop bit (ns; < 0: disabled early); only when known"},
    },
    "required": [
        "t", "raw", "protocol", "unit", "function", "role", "crc_ok", "exception",
        "model", "points", "annotations", "latency_ms", "pair",
    ],
}


def frame_from_record(rec: dict, t0_ns: int = 0) -> Frame:
    """A Frame back from its JSON record (the inverse of records.frame_record, as far as it goes)."""
    raw = bytes.fromhex(rec["raw"])
    f = Frame(rec.get("index", 0), t0_ns + round(rec["t"] * 1e9), t0_ns + round(rec.get("t_end", rec["t"]) * 1e9),
              raw, rec["protocol"], rec.get("unit"), rec.get("function"), crc_ok=rec.get("crc_ok"),
              crc_expected=None if rec.get("crc_expected") is None else int(rec["crc_expected"], 16),
              time_source=rec.get("time_source", "byte"), noise_reason=rec.get("noise_reason"),
              channel=rec.get("channel", ""))
    f.link = rec.get("link", "")
    f.de_on_ns, f.de_off_ns = rec.get("de_on_ns"), rec.get("de_off_ns")
    f.role = rec.get("role", f.role)
    proto = of_frame(f.protocol)
    f.adu = proto.adu_of(raw) if proto is not None else b""  # what the request's fields name (reg:)
    f.pair, f.latency_ms, f.model = rec.get("pair"), rec.get("latency_ms"), rec.get("model")
    f.points, f.exception, f.summary = rec.get("points") or [], rec.get("exception"), rec.get("summary", "")
    f.writes = rec.get("writes") or []  # records written before `writes` existed: the watch stays empty
    f.annotations = [Annotation(a["code"], a["severity"], a["detail"], a["span"][0], a["span"][1])
                     for a in rec.get("annotations") or []]
    return f
