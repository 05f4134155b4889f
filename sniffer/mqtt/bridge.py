"""From decoded frames to MQTT messages, sans-I/O: what to publish, where, and when.

    bridge = Bridge(spec, info, model_name=lambda m: "TECO A510 inverter")
    for msg in bridge.frame(f): ...        # Message(topic, payload, retain)
    for msg in bridge.advance(t_ns): ...    # capture time moved: values held back by --mqtt-interval
    for msg in bridge.finish(): ...         # the end: every value held back, the final health

Topics under PREFIX (the URL's path), LINK the frame's link name ("default" on one line):

    PREFIX/status                   online / offline (retained; the client's last will)
    PREFIX/LINK/UNIT/NAME           a register's latest confirmed value (retained), NAME slugged (a
                                    provisional value has a name of its own: docs/values.md)
    PREFIX/LINK/UNIT/health         the unit's figures (sniffer.analysis.unitfigures; retained, at most once a second)
    PREFIX/LINK/events              warning and error annotations (not retained)

Only confirmed values: a read response's values with a good CRC, and a write request's values
once its acknowledgement (a CRC-good response, not an exception) came; a broadcast write is never
acknowledged and never published.  `--mqtt-interval` keeps at most one message per topic in that
much capture time (the newest value goes out when the interval is over); `--mqtt-changes` sends a
value only when it differs from the last one sent.  Home Assistant discovery (ha.py) is published
the first time a register is.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from typing import NamedTuple

import orjson

from sniffer.analysis.flags import FAULT_CODES
from sniffer.analysis.unitfigures import UnitBook, UnitFigures
from sniffer.mqtt.ha import discovery, health_discovery, slug
from sniffer.mqtt.options import MqttSpec

_NS = 1_000_000_000
HEALTH_EVERY_NS = _NS  # a unit's health topic at most once a second of capture time
_NEVER = 1 << 62
PENDING_WRITES = 1024  # write requests waiting for their acknowledgement (older ones are forgotten)


class Message(NamedTuple):
    topic: str
    payload: bytes
    retain: bool


def iso(wall_ns: int) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(wall_ns // _NS)) + f".{wall_ns % _NS // 1000:06d}Z"


class Bridge:
    def __init__(self, spec: MqttSpec, info, *, model_name=None, shared_names=None) -> None:
        self.spec = spec
        self.prefix = spec.prefix
        self.t0 = info.t0_ns
        self.anchor = info.wall_anchor_ns
        self.model_name = model_name or (lambda model: None)
        self.shared_names = shared_names or (lambda model: frozenset())  # names the model gives several registers
        self.interval_ns = int(spec.interval_s * _NS)
        self.pending: OrderedDict[int, object] = OrderedDict()  # write request index -> frame
        self.names: dict[tuple, str] = {}  # (link, unit, point name, address) -> topic
        self.taken: set[str] = set()
        self.sent: dict[str, tuple] = {}  # topic -> (t_ns, value key) of the last value sent
        self.held: dict[str, tuple] = {}  # topic -> (due t_ns, point, common part, value key)
        self.next_due = _NEVER  # the earliest due time of the held values
        self.book = UnitBook()  # every unit's figures, counted as every view counts them
        self.units: dict[tuple, UnitFigures] = {}  # (link, unit) -> its figures in the book
        self.health_due: dict[tuple, int] = {}  # (link, unit) -> capture time its health is next sent
        self.dirty: set[tuple] = set()
        self.health_announced: set[tuple] = set()
        self.now = 0
        self.values = 0  # confirmed values seen
        self.suppressed = 0  # values not sent: unchanged (--mqtt-changes) or superseded (--mqtt-interval)
        self.events = 0

    # ------------------------------------------------------------ frames
    def frame(self, f) -> list[Message]:
        self.now = max(self.now, f.t_ns)
        link = getattr(f, "link", "") or "default"
        out: list[Message] = []
        fig = self.book.frame(f)
        if fig is not None:
            key = (link, f.unit)
            self.units[key] = fig
            if not fig.ghost:  # a unit named only by CRC-bad frames (a damaged address) gets no health topic
                self.dirty.add(key)
        self._events(f, link, out)
        for points, source, written in self._confirmed(f):
            common = self._common(f, source, written)  # what every value of this group says alike
            for p in points:
                self._value(f, link, p, common, out)
        out += self.advance(f.t_ns)
        return out

    def _confirmed(self, f):
        """(points, the frame they came in) that this frame confirms."""
        if f.role == "request":
            if f.crc_ok and f.points and f.pair is not None:  # a write: wait for its acknowledgement
                self.pending[f.index] = f
                if len(self.pending) > PENDING_WRITES:
                    self.pending.popitem(last=False)
            return ()
        if f.role != "response":
            return ()
        req = self.pending.pop(f.pair, None) if f.pair is not None else None
        if not f.crc_ok or f.exception:
            return ()
        written = req is not None and req.unit == f.unit
        got = [(f.points, f, written)] if f.points else []  # a write's echo (fc 05/06) repeats its values
        if written:
            echoed = {(p.get("name"), p.get("address")) for p in f.points}
            points = [p for p in req.points if (p.get("name"), p.get("address")) not in echoed]
            if points:
                got.append((points, req, True))
        return got

    def _value(self, f, link: str, p: dict, common: dict, out: list[Message]) -> None:
        self.values += 1
        topic, first = self._topic(link, f.unit, f.model, p)
        vkey = (p.get("raw"), p.get("value"), p.get("text"))
        if self.spec.changes:
            last = self.sent.get(topic)
            held = self.held.get(topic)
            if (held[3] if held is not None else last[1] if last is not None else None) == vkey:
                self.suppressed += 1
                return
        if first and self.spec.ha_prefix:
            model = f.model or "generic"
            shared = p.get("name") in self.shared_names(f.model)
            out.append(Message(*discovery(self.spec, link, f.unit, model, self.model_name(model), topic, p, shared),
                               True))
        last = self.sent.get(topic)
        due = last[0] + self.interval_ns if last is not None and self.interval_ns else f.t_ns
        if due > f.t_ns:  # held back (encoded only if it is still the newest when it is due)
            if topic in self.held:
                self.suppressed += 1
            self.held[topic] = (due, p, common, vkey)
            self.next_due = min(self.next_due, due)
            return
        self.held.pop(topic, None)
        self.sent[topic] = (f.t_ns, vkey)
        out.append(Message(topic, _payload(p, common), True))

    def _topic(self, link: str, unit: int, model: str | None, p: dict) -> tuple[str, bool]:
        """The register's topic (and whether it is new): its name slugged; a name the model gives several
        registers (or one taken already) gets the address, so every register has its own topic."""
        key = (link, unit, p.get("name"), p.get("address"))
        topic = self.names.get(key)
        if topic is not None:
            return topic, False
        base = f"{self.prefix}/{slug(link)}/{unit}/"
        name = slug(p.get("name") or f"register_{p.get('address')}")
        if name in ("health", "events") or p.get("name") in self.shared_names(model) or base + name in self.taken:
            name = f"{name}_{p.get('address')}"
        topic = self.names[key] = base + name
        self.taken.add(topic)
        return topic, True

    def _common(self, f, source, written: bool) -> dict:
        d = self._when(f.t_ns)
        d.update(model=f.model, frame=f.index, written=written,
                 quality={"crc_ok": bool(f.crc_ok and source.crc_ok), "annotations": _codes(f, source)})
        return d

    def _when(self, t_ns: int) -> dict:
        t_rel = t_ns - self.t0
        if self.anchor:
            wall = self.anchor + t_rel
            return {"time": iso(wall), "epoch": round(wall / _NS, 6), "t": round(t_rel / _NS, 6)}
        return {"time": None, "epoch": None, "t": round(t_rel / _NS, 6)}  # a capture that does not know its clock

    def _events(self, f, link: str, out: list[Message]) -> None:
        for a in f.annotations:
            if a.severity == "info" and a.code not in FAULT_CODES:
                continue
            self.events += 1
            d = {"code": a.code, "severity": a.severity, "detail": a.detail, "unit": f.unit, "function": f.function,
                 "role": f.role, "model": f.model, "frame": f.index, "summary": f.summary[:300]}
            d.update(self._when(f.t_ns))
            out.append(Message(f"{self.prefix}/{slug(link)}/events", orjson.dumps(d), False))

    # ------------------------------------------------------------ time
    def advance(self, t_ns: int) -> list[Message]:
        """Capture time is t_ns: the held values and the health topics that are due."""
        self.now = max(self.now, t_ns)
        out: list[Message] = []
        if self.held and self.next_due <= t_ns:
            nxt = _NEVER
            for topic, (due, p, common, vkey) in list(self.held.items()):
                if due <= t_ns:
                    del self.held[topic]
                    self.sent[topic] = (t_ns, vkey)
                    out.append(Message(topic, _payload(p, common), True))
                else:
                    nxt = min(nxt, due)
            self.next_due = nxt
        if self.dirty:
            every = max(HEALTH_EVERY_NS, self.interval_ns)
            for key in list(self.dirty):
                if self.health_due.get(key, 0) <= t_ns:
                    self.health_due[key] = t_ns + every
                    self.dirty.discard(key)
                    out += self._health(key)
        return out

    def finish(self) -> list[Message]:
        """The end of the capture: every held value and every unit's final health."""
        out = [Message(topic, _payload(p, common), True) for topic, (_due, p, common, _v) in self.held.items()]
        self.held.clear()
        for key in sorted(self.dirty, key=str):
            out += self._health(key)
        self.dirty.clear()
        return out

    def _health(self, key: tuple) -> list[Message]:
        link, unit = key
        st = self.units[key]
        topic = f"{self.prefix}/{slug(link)}/{unit}/health"
        out = []
        if self.spec.ha_prefix and key not in self.health_announced:
            self.health_announced.add(key)
            model = st.model or "generic"
            out.append(Message(*health_discovery(self.spec, link, unit, model, self.model_name(model), topic), True))
        lat = st.latency.figures()
        d = {"unit": unit, "model": st.model, **st.counts(),
             "errors": st.crc_errors + st.exceptions + st.timeouts,
             "latency_ms": {"n": lat["lat_n"], "min": lat["lat_min"], "median": lat["lat_median"],
                            "p95": lat["lat_p95"], "p99": lat["lat_p99"], "max": lat["lat_max"],
                            "exact": lat["lat_exact"]},
             "poll_rate": round(st.poll_rate, 3)}
        d.update(self._when(st.last_seen_ns or self.now))
        out.append(Message(topic, orjson.dumps(d), True))
        return out


def _payload(p: dict, common: dict) -> bytes:
    """A value's JSON: the point (value, unit, raw, name, address, text, id), then when and how it came."""
    d = {"value": p.get("value"), "unit": p.get("unit"), "raw": p.get("raw"), "name": p.get("name"),
         "address": p.get("address")}
    if p.get("text") is not None:
        d["text"] = p["text"]
    if p.get("id"):
        d["id"] = p["id"]
    if p.get("provisional"):
        d["provisional"] = True  # scaled through a register not known yet: in %, on a topic of its own
    d.update(common)
    return orjson.dumps(d)


def _codes(f, source) -> list[str]:
    """The annotation codes of the frames that confirmed a value (a write: its request and the answer)."""
    codes = [a.code for a in source.annotations]
    if source is not f:
        codes += [a.code for a in f.annotations]
    return codes


__all__ = ["Bridge", "Message"]
