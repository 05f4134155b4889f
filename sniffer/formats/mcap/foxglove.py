"""What makes a capture's MCAP Foxglove-native: the parts Foxglove's panels and fleet tools read.

Beside /capture, /raw and /frames (sniffer.formats.mcap.format), McapSink writes (docs/foxglove.md):

* metadata ``foxglove``: ``deviceName`` (the recording's device for Foxglove's agent and Edge
  Sites, which skip a file naming none: `--foxglove-device`, else what the capture recorded, else
  this host's name), ``links`` (the link names, comma-separated), ``line`` (each link's settings)
  and ``sniffer`` (the version);
* ``/annotations`` (schema ``foxglove.Log``, JSON): the frames' annotations for the Log panel.
  Warnings and errors every time, an info note the first time its code shows for a unit (the
  A510's "0.01 Hz assumed" would otherwise fill the panel); ``name`` the unit (``u3``,
  ``LINK/u3``, or the link for noise), ``message`` the code, its detail and the frame's summary,
  ``file`` the annotation code and ``line`` the frame number;
* ``/values/[LINK/]uUNIT/NAME`` (schema ``sniffer.Value``): one topic per register seen, so the Plot
  panel plots ``/values/u1/Output_frequency.value``.  Only confirmed values: those a CRC-good
  response carried, and those of a write request once a CRC-good response (no exception)
  acknowledged it; never a broadcast write, which nobody answers.  NAME is the register's name up
  to its first " (", letters and digits with "_" between; a name two registers of one unit share
  gets the address (``_2524H``).  A provisional value (scaled through a register not known yet,
  docs/values.md) is a register of its own name: its whole name is the topic
  (``Output_frequency_pct_of_Cn_02``), never the scaled value's.  The channel's metadata holds
  the full name, id, address, unit, link and model.  A register's samples are thinned without
  changing its plot (`_sample`): a change, the sample before it, one every KEEP_NS while nothing
  changes, the last at the end (`finish`); every poll's value stays in /frames.  A message leaves
  out what it has no value for (Foxglove's JSON Schema reader takes one type per field, no null);
* one attachment per model seen: its register map (decoders.mapfile).

Why a topic per register and not one `/values` topic: a drive model has hundreds of registers,
but a line polls tens, and only registers seen get a channel (a few hundred bytes each); the Plot
panel, the topic list and the Raw Messages panel then take a register by its topic alone, where
one topic would need a filter in every path (``/values.points[:]{name=="Output frequency"}``) that
Foxglove evaluates on every message of every register.  A message per sample costs its record and
index entry (about 30 bytes on disk): the thinning keeps that to the samples a plot needs.

Sans-I/O: `Foxglove` turns frames (Frame objects, or the /frames records a trigger window's ring
holds) into (topic, time, JSON) messages and says which topics and models are new.
"""

from __future__ import annotations

import math
import os
import re
import socket
from collections import OrderedDict

import msgspec

from sniffer import __version__
from sniffer.codes import Annotation
from sniffer.events import CaptureInfo

METADATA_NAME = "foxglove"
LOG_TOPIC = "/annotations"
LOG_SCHEMA_NAME = "foxglove.Log"
VALUES_PREFIX = "/values/"
VALUE_SCHEMA_NAME = "sniffer.Value"
PENDING_WRITES = 1024  # write requests waiting for their acknowledgement (older ones are forgotten)
KEEP_NS = 10_000_000_000  # a register's unchanged value is written again after this much capture time
LEVELS = {"info": 2, "warning": 3, "error": 4}  # foxglove.LogLevel: UNKNOWN 0, DEBUG 1, INFO 2, WARNING 3, ERROR 4

# foxglove.Log as Foxglove publishes it for JSON (its schemas' jsonschema/Log.json), the fields we fill
LOG_SCHEMA = {
    "title": LOG_SCHEMA_NAME,
    "description": "A log message",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object", "title": "time", "description": "Timestamp of log message",
            "properties": {"sec": {"type": "integer", "minimum": 0},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}},
        },
        "level": {
            "title": "foxglove.LogLevel", "description": "Log level",
            "oneOf": [{"title": t, "const": n} for n, t in enumerate(("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR",
                                                                       "FATAL"))],
        },
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
    },
    "required": ["timestamp", "level", "message", "name", "file", "line"],
}

# Foxglove's JSON Schema reader takes one type per field (no null, no list of types, no untyped
# field, no array of arrays): a field without a value is left out of the message instead.
VALUE_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": VALUE_SCHEMA_NAME,
    "description": "One register's confirmed value (a CRC-good response's, or a write's its response "
                   "acknowledged); the channel's metadata names the register",
    "type": "object",
    "properties": {
        "value": {"type": "number", "description": "scaled as the model says (absent: not a number; see text)"},
        "raw": {"type": "integer", "description": "as on the wire (absent for a string's registers)"},
        "unit": {"type": "string"},
        "text": {"type": "string", "description": "the value in words: an enum, bits, a string"},
        "provisional": {"type": "boolean", "description": "scaled through a register not known yet: in % of it"},
        "frame": {"type": "integer", "minimum": 0, "description": "the frame that carried (or acknowledged) it"},
    },
    "required": ["frame"],
}

_NOT_NAME = re.compile(r"[^0-9A-Za-z]+")


def topic_part(text: str) -> str:
    """Letters and digits of `text` with "_" between, "%" as "pct" (a topic path element Foxglove's paths
    take bare)."""
    return _NOT_NAME.sub("_", text.replace("%", " pct ")).strip("_")


def device_name(info: CaptureInfo) -> str:
    return str(info.extra.get("device_name") or "") or socket.gethostname() or "sniffer"


def link_lines(info: CaptureInfo) -> list[tuple[str, str]]:
    """(link name, its line settings) of each link: one for a one-line capture (named for its port)."""
    links = info.links or [{
        "name": os.path.basename(info.port.rstrip("/")) or info.port or info.source, "baud": info.baud,
        "parity": info.parity, "stopbits": info.stopbits, "databits": info.databits, "protocol": info.protocol}]
    out = []
    for x in links:
        fmt = f"{x.get('databits') or 8}{x.get('parity') or '?'}{x.get('stopbits') or '?'}"
        out.append((str(x.get("name", "")), f"{x.get('baud') or '?'} {fmt} {x.get('protocol') or ''}".rstrip()))
    return out


def metadata(info: CaptureInfo) -> dict[str, str]:
    """The `foxglove` metadata record."""
    lines = link_lines(info)
    line = lines[0][1] if len(lines) == 1 else "; ".join(f"{n}: {s}" for n, s in lines)
    return {"deviceName": device_name(info), "links": ", ".join(n for n, _ in lines), "line": line,
            "sniffer": info.sniffer_version or __version__}


def _value_json(key: tuple, frame: int) -> bytes:
    """A sample's message: the fields it has (VALUE_SCHEMA)."""
    value, raw, unit, text, provisional = key
    d = {} if value is None else {"value": value}
    if type(raw) is int:
        d["raw"] = raw
    if unit is not None:
        d["unit"] = unit
    if text is not None:
        d["text"] = text
    if provisional:
        d["provisional"] = True
    d["frame"] = frame
    return msgspec.json.encode(d)


class _Record:
    """A /frames record (a dict) with the Frame attributes `Foxglove.frame` reads."""

    __slots__ = ("index", "unit", "link", "role", "crc_ok", "exception", "model", "pair", "points", "writes",
                 "annotations", "summary")

    def __init__(self, d: dict) -> None:
        for k in ("index", "unit", "role", "crc_ok", "exception", "model", "pair", "summary"):
            setattr(self, k, d.get(k))
        self.link = d.get("link") or ""
        self.points = d.get("points") or []
        self.writes = d.get("writes") or []
        self.annotations = [Annotation(a.get("code", ""), a.get("severity", ""), a.get("detail", ""), 0, 0)
                            for a in d.get("annotations") or ()]


class Foxglove:
    """Frames in, Foxglove messages out (see the module doc); `new_topics` / `new_models` say what the
    writer must define (a channel, an attachment) before the messages of `frame()` are written."""

    def __init__(self, info: CaptureInfo) -> None:
        self.t0 = info.t0_ns
        self.anchor = info.wall_anchor_ns
        self.topics: dict[tuple, str] = {}  # (link, unit, name, address) -> topic
        self.channel_meta: dict[str, dict[str, str]] = {}  # topic -> its channel metadata
        self.taken: set[str] = set()
        self.pending: OrderedDict[int, tuple] = OrderedDict()  # write request index -> (link, unit, points)
        self.last: dict[str, list] = {}  # topic -> [value key, time written, (time, frame) held or None]
        self.told: set[tuple] = set()  # (link, unit, code) of the info notes logged once
        self.models: set[str] = set()
        self.new_topics: list[str] = []
        self.new_models: list[str] = []

    def record(self, data: bytes, t_ns: int) -> list[tuple[str, int, bytes]]:
        """`frame` for an encoded /frames record."""
        return self.frame(_Record(msgspec.json.decode(data)), t_ns)

    def frame(self, f, t_ns: int) -> list[tuple[str, int, bytes]]:
        """The (topic, time, JSON) messages of one frame, in the order to write them."""
        out: list[tuple[str, int, bytes]] = []
        link = f.link
        model = f.model
        if model and model not in self.models:
            self.models.add(model)
            self.new_models.append(model)
        if f.annotations:
            self._log(f, link, t_ns, out)
        role = f.role
        if role == "request":
            if f.crc_ok and f.pair is not None and f.unit and f.points:  # a write, until its answer comes
                self.pending[f.index] = (link, f.unit, f.points)
                if len(self.pending) > PENDING_WRITES:
                    self.pending.popitem(last=False)
        elif role == "response":
            req = self.pending.pop(f.pair, None) if f.pair is not None else None
            if f.writes and f.crc_ok and not f.exception and f.unit:  # what the decoder took as confirmed
                block = getattr(f, "_points", None)
                if type(block) is not list and hasattr(block, "samples"):
                    self._block(f, link, t_ns, block, out)
                    points = []  # a read's values: no write of the request to add
                else:
                    points = f.points
                    self._values(f, link, t_ns, points, out)
                if req is not None and req[:2] == (link, f.unit):
                    echoed = {(p.get("name"), p.get("address")) for p in points}
                    self._values(f, link, t_ns, [p for p in req[2]
                                                 if (p.get("name"), p.get("address")) not in echoed], out)
        return out

    def finish(self) -> list[tuple[str, int, bytes]]:
        """The end of the capture: every register's last sample not written yet (its plot reaches the end)."""
        out = [(topic, held[0], _value_json(st[0], held[1]))
               for topic, st in self.last.items() if (held := st[2]) is not None]
        for st in self.last.values():
            st[2] = None
        return out

    # ------------------------------------------------------------ values
    def _values(self, f, link: str, t_ns: int, points: list[dict], out: list) -> None:
        for p in points:
            address = p.get("address")
            if address is None or "part" in p:
                continue  # a register whose number is unknown, or one word of a value of several registers
            value, text = p.get("value"), p.get("text")
            if type(value) is str:
                value, text = None, value if text is None else text
            elif type(value) not in (int, float) or (type(value) is float and not math.isfinite(value)):
                value = None
            self._sample(f, link, t_ns, p.get("name") or "", address,
                         (value, p.get("raw"), p.get("unit"), text, p.get("provisional") is True), p.get("id"), out)

    def _block(self, f, link: str, t_ns: int, block, out: list) -> None:
        """A block of unnamed registers (frame.PointBlock): raw numbers, read without building dicts."""
        for name, address, v in block.samples():
            self._sample(f, link, t_ns, name, address, (v, v, None, None, False), None, out)

    def _sample(self, f, link: str, t_ns: int, name: str, address: int, key: tuple, pid, out: list) -> None:
        """One register's sample, thinned without changing its plot: a change, the sample before it, and
        one every KEEP_NS while nothing changes (a polyline loses only points between equal ones)."""
        topic = self.topics.get((link, f.unit, name, address)) or self._topic(f, link, name, address, pid, key[4])
        st = self.last.get(topic)
        if st is not None:
            if st[0] == key and t_ns - st[1] < KEEP_NS:
                st[2] = (t_ns, f.index)  # held: written if the next sample differs
                return
            held = st[2]
            if held is not None and st[0] != key:
                out.append((topic, held[0], _value_json(st[0], held[1])))
        out.append((topic, t_ns, _value_json(key, f.index)))
        self.last[topic] = [key, t_ns, None]

    def _topic(self, f, link: str, name: str, address: int, pid, provisional: bool = False) -> str:
        key = (link, f.unit, name, address)
        base = VALUES_PREFIX + (f"{topic_part(link)}/" if link else "") + f"u{f.unit}/"
        short = (topic_part(name) if provisional else topic_part(name.split(" (")[0])) or topic_part(name) or "register"
        topic = base + short
        if topic in self.taken:
            topic = f"{base}{short}_{address:04X}H"
            n = 2
            while topic in self.taken:
                topic, n = f"{base}{short}_{address:04X}H_{n}", n + 1
        self.taken.add(topic)
        self.topics[key] = topic
        meta = {"name": name, "id": str(pid or ""), "address": str(address), "unit": str(f.unit), "link": link,
                "model": f.model or ""}
        self.channel_meta[topic] = {k: v for k, v in meta.items() if v}  # repeated in every segment's summary
        self.new_topics.append(topic)
        return topic

    # ------------------------------------------------------------ the log
    def _log(self, f, link: str, t_ns: int, out: list) -> None:
        who = f"u{f.unit}" if f.unit is not None else "line"
        if link:
            who = f"{link}/{who}" if f.unit is not None else link
        wall = max(0, self.anchor + (t_ns - self.t0))
        stamp = {"sec": wall // 1_000_000_000, "nsec": wall % 1_000_000_000}
        for a in f.annotations:
            level = LEVELS.get(a.severity, 0)
            if level == 2:
                key = (link, f.unit, a.code)
                if key in self.told:
                    continue
                self.told.add(key)
            text = f"{a.code}: {a.detail}" if a.detail else a.code
            out.append((LOG_TOPIC, t_ns, msgspec.json.encode({
                "timestamp": stamp, "level": level, "message": f"{text} | #{f.index} {f.summary or ''}"[:1000],
                "name": who, "file": a.code, "line": f.index or 0})))


__all__ = ["LOG_SCHEMA", "LOG_TOPIC", "METADATA_NAME", "VALUE_SCHEMA", "VALUES_PREFIX", "Foxglove", "device_name",
           "metadata", "topic_part"]
