"""The MCAP capture format: topics, schemas and the /raw event codec.

Shared by the writer (formats/mcap/sink.py), the reader (formats/mcap/reader.py),
`sniffer repair` and the progress bar; none of them imports another.

Channels (JSON messages described by JSON Schema, so Foxglove can plot fields):

* ``/capture`` -- one message, the first in the file: the CaptureInfo (line
  settings, t0, wall anchor, low-latency state, device map).  The same dict is
  MCAP metadata ``sniffer.capture``.
* ``/raw`` -- one message per source event (Chunk / Tick / Gap): the replay
  input, enough to re-frame and re-decode with other settings (`encode_event`).
* ``/frames`` -- one message per decoded frame: the JSONL record of
  sniffer.formats.records (schema FRAME_SCHEMA).

log_time = publish_time = wall_anchor_ns + (t_ns - t0_ns), clamped to >= 0.

What Foxglove's panels read besides (the `foxglove` metadata, /annotations as
foxglove.Log, /values/... per register, the register maps as attachments) is
sniffer.formats.mcap.foxglove; a replay reads /capture and /raw only.

Several links on one timeline (`sniffer live P1 P2 ...`, `--tap`, a bus file's
``[[links]]``): still one /raw and one /frames channel, one clock; every /raw
event and every /frames record of such a capture carries a ``link`` field (the
link's name), and /capture's ``links`` lists the links in order (name, ports,
channels, the settings each was captured with).  A replay hands each link's
events to that link's own framer, pairer and decoders, in the order written,
so it re-splits the links exactly.  A one-line capture has no ``link`` field
and no ``links`` list: its files are as they always were.  ``channel`` is the
wire within one link: with --tap, "master" (the master's pair: requests) or
"slaves" (the slaves' pair: responses).
"""

from __future__ import annotations

import msgspec

from sniffer.events import TIME_SOURCES, CaptureInfo, Chunk, Gap, Tick
from sniffer.formats.records import FRAME_SCHEMA
from sniffer.hot import HOT

MAGIC = b"\x89MCAP0\r\n"
CAPTURE_TOPIC = "/capture"
RAW_TOPIC = "/raw"
FRAMES_TOPIC = "/frames"
METADATA_NAME = "sniffer.capture"
RAW_FORMAT = "1"  # channel metadata "sniffer.format": bump when /raw changes incompatibly
# a compact file's /raw (segments, trigger windows): a message holds the events of up to a second, a JSON
# array of format 1's objects, and there is no /frames channel (a replay decodes them again, exactly)
RAW_BATCH_FORMAT = "2"
RAW_FORMATS = (RAW_FORMAT, RAW_BATCH_FORMAT)
BATCH_NS = 1_000_000_000  # a batch spans at most this much capture time (and ends at every flush)

RAW_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sniffer.RawEvent",
    "description": "One source event: bytes read, a silence tick, or a gap in the capture",
    "type": "object",
    "properties": {
        "kind": {"type": "string", "enum": ["chunk", "tick", "gap"]},
        "t_ns": {
            "type": "integer",
            "description": "capture monotonic clock, ns (chunk: first byte if per-byte, else when the read returned)",
        },
        "data": {"type": "string", "description": "chunk bytes, hex"},
        "byte_dt_ns": {
            "type": ["array", "null"],
            "items": {"type": "integer"},
            "description": "start time of each byte as an offset from t_ns; null: one time per read",
        },
        "flags": {
            "type": "array",
            "description": "[byte offset, 'framing'|'parity'] UART errors",
            "items": {"type": "array", "prefixItems": [{"type": "integer"}, {"type": "string"}]},
        },
        "channel": {"type": "string", "description": "the wire within the link (--tap: master or slaves)"},
        "link": {"type": "string", "description": "the link's name (captures of several links only)"},
        "unseen_ns": {"type": "integer", "description": "chunk read live after the reader stalled: the port "
                      "was last seen empty this long before t_ns (the bytes came within it); absent: it "
                      "looked every tick, or not known"},
        "de": {"type": "array", "items": {"type": ["integer", "null"]}, "minItems": 2, "maxItems": 2,
               "description": "chunk of a logic analyzer's --de capture, sent while the slave's driver was "
                              "enabled: [rise, fall] of its driver-enable line (ns; null: before the capture / "
                              "not known); absent: not in a DE window"},
        "packet": {"type": "boolean", "description": "chunk: one packet of a capturing tool (pcap), whose edges no "
                   "frame spans; absent: false"},
        "t_end_ns": {"type": "integer", "description": "gap: end of the interruption"},
        "reason": {"type": "string", "description": "gap: why the source was interrupted"},
    },
    "required": ["kind", "t_ns"],
}

CAPTURE_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sniffer.CaptureInfo",
    "description": "How the capture was taken: serial settings, clocks, devices",
    "type": "object",
    "properties": {
        "source": {"type": "string"},
        "port": {"type": "string"},
        "baud": {"type": ["integer", "null"]},
        "parity": {"type": ["string", "null"]},
        "stopbits": {"type": ["integer", "null"]},
        "databits": {"type": "integer"},
        "time_source": {"type": "string", "enum": list(TIME_SOURCES)},
        "t0_ns": {"type": "integer"},
        "wall_anchor_ns": {"type": "integer"},
        "low_latency": {"type": "object"},
        "devices": {"type": "object"},
        "protocol": {"type": "string"},
        "sniffer_version": {"type": "string"},
        "extra": {"type": "object"},
        "links": {"type": "array", "items": {"type": "object"},
                  "description": "several links: name, ports, channels and settings of each, in order"},
    },
}


RAW_BATCH_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sniffer.RawEvents",
    "description": "The source events of up to a second, in order (sniffer.format 2)",
    "type": "array",
    "items": {k: v for k, v in RAW_SCHEMA.items() if k != "$schema"},
}

# (topic, schema name, JSON schema) of every channel, in the order a writer registers them
CHANNELS = (
    (CAPTURE_TOPIC, "sniffer.CaptureInfo", CAPTURE_SCHEMA),
    (RAW_TOPIC, "sniffer.RawEvent", RAW_SCHEMA),
    (FRAMES_TOPIC, "sniffer.Frame", FRAME_SCHEMA),
)


def encode_event(ev: Chunk | Tick | Gap) -> bytes:
    """The /raw message of one event (exactly invertible by `decode_event`)."""
    if type(ev) is Chunk:
        t = ev.t_ns
        d = {
            "kind": "chunk",
            "t_ns": t,
            "data": ev.data.hex(),
            "byte_dt_ns": None if ev.byte_t_ns is None else [b - t for b in ev.byte_t_ns],
            "flags": [[i, f] for i, f in ev.flags],
            "channel": ev.channel,
        }
        if ev.unseen_ns is not None:
            d["unseen_ns"] = ev.unseen_ns
        if ev.de is not None:
            d["de"] = list(ev.de)
        if ev.packet:
            d["packet"] = True
    elif type(ev) is Tick:
        d = {"kind": "tick", "t_ns": ev.t_ns}
    elif type(ev) is Gap:
        d = {"kind": "gap", "t_ns": ev.t_ns, "t_end_ns": ev.t_end_ns, "reason": ev.reason}
        if ev.state:
            d["state"] = ev.state
    else:
        raise TypeError(f"not a source event: {ev!r}")
    if ev.link:
        d["link"] = ev.link
    return msgspec.json.encode(d)


# the messages this sniffer writes itself, read in C (sniffer/_hot.c decode_raw); None: every message by
# decode_event_py, the reference
_DECODE_RAW = None if HOT is None else HOT.decode_raw


def encode_batch(encoded: list[bytes]) -> bytes:
    """The /raw message of format 2 holding these encoded events (encode_event's)."""
    return b"[" + b",".join(encoded) + b"]"


def decode_batch(data: bytes) -> list[Chunk | Tick | Gap]:
    """The events of a format 2 /raw message (kinds this version does not know left out); ValueError as
    decode_event."""
    items = msgspec.json.decode(data)
    if not isinstance(items, list):
        raise ValueError("a /raw message of format 2 is not a list")
    return [ev for ev in map(_event, items) if ev is not None]


def decode_event(data: bytes) -> Chunk | Tick | Gap | None:
    """Event from a /raw message; None for a kind this version does not know.

    Raises ValueError (or KeyError/TypeError) on a malformed message.
    """
    if _DECODE_RAW is not None:
        ev = _DECODE_RAW(data, Chunk, Tick)  # None: not a shape it reads (another tool's, damaged, a gap...)
        if ev is not None:
            return ev
    return decode_event_py(data)


def decode_event_py(data: bytes) -> Chunk | Tick | Gap | None:
    """decode_event in Python: the reference, and the reader of every message the compiled one leaves."""
    return _event(msgspec.json.decode(data))


def _event(d: dict) -> Chunk | Tick | Gap | None:
    kind = d["kind"]
    t = int(d["t_ns"])
    link = str(d.get("link") or "")
    if kind == "chunk":
        raw = bytes.fromhex(d["data"])
        dt = d.get("byte_dt_ns")
        byte_t = None if dt is None else tuple(t + int(x) for x in dt)
        if byte_t is not None and len(byte_t) != len(raw):
            raise ValueError("byte_dt_ns and data differ in length")
        flags = tuple((int(i), str(f)) for i, f in d.get("flags") or ())
        unseen = d.get("unseen_ns")
        de = d.get("de")
        if de is not None:
            rise, fall = de
            de = (None if rise is None else int(rise), None if fall is None else int(fall))
        return Chunk(t, raw, byte_t, flags, str(d.get("channel") or ""), link, None if unseen is None else int(unseen),
                     de, bool(d.get("packet")))
    if kind == "tick":
        return Tick(t, link)
    if kind == "gap":
        state = d.get("state")
        return Gap(t, int(d["t_end_ns"]), str(d["reason"]), link, state if isinstance(state, dict) else None)
    return None


def info_to_metadata(info: CaptureInfo) -> dict[str, str]:
    """MCAP metadata is a string map: each CaptureInfo field, JSON-encoded."""
    return {k: msgspec.json.encode(v).decode() for k, v in info.to_dict().items()}


def info_from_metadata(meta: dict[str, str]) -> CaptureInfo:
    return CaptureInfo.from_dict({k: msgspec.json.decode(v) for k, v in meta.items()})
