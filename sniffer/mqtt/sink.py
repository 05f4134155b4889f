"""The MQTT sink: decoded frames -> Bridge (what to publish) -> Publisher (the client's thread).

The session adds it when the capture has `--mqtt URL` (Session.open), as it adds the trigger sink,
so live, demo, replay and serve's capture process publish alike; it gets `advance(t)` with every
source event's time (a value held back by --mqtt-interval goes out on a quiet line too).
`status()` gives {"mqtt": {...}} for the capture's status (connected, published, queued, dropped).
"""

from __future__ import annotations

from collections import Counter

from sniffer.sinks.base import Sink
from sniffer.mqtt.bridge import Bridge
from sniffer.mqtt.client import Publisher
from sniffer.mqtt.options import MqttSpec


class MqttSink(Sink):
    def __init__(self, spec: MqttSpec, *, registry=None, report=None, publisher: Publisher | None = None) -> None:
        self.spec = spec
        self.registries = [registry] if registry is not None else []  # a capture of several links: each link's
        self.publisher = publisher or Publisher(spec, report=report)
        self.bridge: Bridge | None = None
        self._shared: dict = {}

    def start(self, info) -> None:
        self.bridge = Bridge(self.spec, info, model_name=self._model_name, shared_names=self._shared_names)
        self.publisher.start()

    def frame(self, frame) -> None:
        send = self.publisher.send
        for m in self.bridge.frame(frame):
            send(*m)

    def advance(self, t_ns: int) -> None:
        if self.bridge is not None:
            send = self.publisher.send
            for m in self.bridge.advance(t_ns):
                send(*m)

    def close(self) -> None:
        if self.bridge is not None:
            for m in self.bridge.finish():
                self.publisher.send(*m)
            self.publisher.close()

    def status(self) -> dict:
        st = self.publisher.status()
        b = self.bridge
        if b is not None:
            st.update(values=b.values, suppressed=b.suppressed, events=b.events, topics=len(b.names))
        return {"mqtt": st}

    def _map(self, model: str | None):
        for registry in self.registries:
            dec = getattr(registry, "decoders", {}).get(model)
            if dec is not None:
                return getattr(dec, "map", None)  # a model of register tables (decoders.table_decoder.TableDecoder)
        return None

    def _model_name(self, model: str) -> str | None:
        regmap = self._map(model)
        return getattr(getattr(regmap, "model", None), "name", None)  # a register map's ModelInfo

    def _shared_names(self, model: str | None) -> frozenset:
        got = self._shared.get(model)
        if got is None:
            regmap = self._map(model)
            rows = [*regmap.registers.values(), *regmap.inputs.values()] if regmap is not None else []
            names = Counter(r.name for r in rows)
            got = self._shared[model] = frozenset(n for n, k in names.items() if k > 1)
        return got


def mqtt_sink(spec, registry) -> MqttSink:
    """The sink a capture with --mqtt gets (Session.open)."""
    return MqttSink(spec.mqtt, registry=registry)


__all__ = ["MqttSink", "mqtt_sink"]
