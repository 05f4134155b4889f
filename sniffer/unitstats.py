"""What is counted per unit: requests, answers, errors, faults, latencies, the poll rate (the TUI's Units tab,
the MQTT bridge's health topics)."""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, field

from .frame import Frame
from .frameflags import F_EXC, F_FAULT, F_TIMEOUT

_LAT_KEEP = 2048  # latencies kept per unit for the median
_RATE_WINDOW_NS = 10_000_000_000  # poll rate over the last 10 s of capture time


@dataclass
class UnitStats:
    unit: object  # frame.unit_key: the number, or (link, number) in a capture of several links
    model: str | None = None
    requests: int = 0
    responses: int = 0
    crc_errors: int = 0
    exceptions: int = 0
    timeouts: int = 0
    faults: int = 0  # answers reporting a fault or alarm (model.fault / model.alarm)
    good: int = 0  # CRC-good frames: a unit seen only in damaged frames may be a ghost (a corrupted address)
    lat_min: float | None = None
    lat_max: float | None = None
    latencies: deque = field(default_factory=lambda: deque(maxlen=_LAT_KEEP))
    recent_requests: deque = field(default_factory=deque)  # t_ns of requests in the rate window
    last_seen_ns: int = 0

    @property
    def lat_median(self) -> float | None:
        return statistics.median(self.latencies) if self.latencies else None

    @property
    def poll_rate(self) -> float:
        """Requests per second over the last window of capture time."""
        r = self.recent_requests
        if len(r) < 2:
            return 0.0
        span = (r[-1] - r[0]) / 1e9
        return (len(r) - 1) / span if span > 0 else 0.0

    def count(self, f: Frame, fl: int) -> None:
        """Count frame `f` of this unit (`fl`: its frame_flags)."""
        if f.model:
            self.model = f.model
        self.last_seen_ns = f.t_ns
        if f.role == "request":
            self.requests += 1
            r = self.recent_requests
            r.append(f.t_ns)
            while r and f.t_ns - r[0] > _RATE_WINDOW_NS:
                r.popleft()
        elif f.role == "response":
            self.responses += 1
        if f.crc_ok is False:
            self.crc_errors += 1
        elif f.crc_ok:
            self.good += 1
        if fl & F_EXC:
            self.exceptions += 1
        if fl & F_TIMEOUT:
            self.timeouts += 1
        if fl & F_FAULT:
            self.faults += 1
        lat = f.latency_ms
        if lat is not None and f.role == "response":
            self.latencies.append(lat)
            self.lat_min = lat if self.lat_min is None else min(self.lat_min, lat)
            self.lat_max = lat if self.lat_max is None else max(self.lat_max, lat)
