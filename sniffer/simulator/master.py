"""The simulated PLC: what it asks for, in which order, with which values.

It decides requests only; the bus (bus.py) decides when they go out and what
happens to them on the wire.  The PLC keeps its own idea of each drive's
command word and setpoint and writes those, the way a real program writes
its tags, so the writes on the line change over time as an operator would
change them.
"""

from __future__ import annotations

import random
import struct
from collections import deque
from dataclasses import dataclass

from .scenario import PollSpec, Scenario


@dataclass(frozen=True, slots=True)
class Request:
    unit: int
    pdu: bytes  # function + data, without address and CRC


class Master:
    def __init__(self, scenario: Scenario, rng: random.Random) -> None:
        self.sc = scenario
        self.rng = rng
        self.control = scenario.drive_map.control
        self.units = [u.unit for u in scenario.units]
        # units named only by a poll (e.g. one that is not on the bus) are polled too
        extra = sorted({u for p in scenario.polls for u in p.units} - set(self.units))
        self.targets = self.units + extra
        lo, hi = scenario.setpoint_range_hz
        self.setpoint = {u: round(rng.uniform(max(lo, 10.0), hi) * 2) / 2 for u in self.units}
        self.run = dict.fromkeys(self.units, True)
        self.coil = dict.fromkeys(self.targets, False)
        self.queue: deque[Request] = deque()  # writes the operator triggered
        self.next_change_ns = int(scenario.setpoint_change_s * 1e9)
        # start-up: put every drive in run with its setpoint
        for u in self.units:
            self.queue.append(Request(u, self._write_multi(u, self.control, 2)))

    def command_word(self, unit: int) -> int:
        return 0x0001 if self.run.get(unit) else 0x0000

    def setpoint_word(self, unit: int) -> int:
        return round(self.setpoint.get(unit, 0.0) * 100)

    def operator(self, t_ns: int) -> None:
        """Now and then someone changes a drive's setpoint (or stops it)."""
        if not self.units or t_ns < self.next_change_ns:
            return
        self.next_change_ns = t_ns + int(self.sc.setpoint_change_s * 1e9)
        u = self.rng.choice(self.units)
        lo, hi = self.sc.setpoint_range_hz
        new = round(self.rng.uniform(lo, hi) * 2) / 2
        if self.rng.random() < 0.15:
            new = 0.0
        was_running = self.run[u]
        self.setpoint[u] = new
        self.run[u] = new > 0
        self.queue.append(Request(u, self._write_single(self.control + 1, self.setpoint_word(u))))
        if self.run[u] != was_running:
            self.queue.append(Request(u, self._write_single(self.control, self.command_word(u))))

    def cycle(self, n: int) -> list[Request]:
        """The requests of poll cycle n: operator writes first, then the polls."""
        out = list(self.queue)
        self.queue.clear()
        for u in self.targets:
            for p in self.sc.polls:
                if p.units and u not in p.units:
                    continue
                if not p.units and u not in self.units:
                    continue
                if n % p.every or (p.prob < 1.0 and self.rng.random() >= p.prob):
                    continue
                out.append(Request(u, self.build(u, p)))
        return out

    def broadcast(self) -> Request:
        """Unit 0 write: every drive gets the same setpoint (a line-wide speed change)."""
        lo, hi = self.sc.setpoint_range_hz
        value = round(self.rng.uniform(max(lo, 10.0), hi) * 2) / 2
        for u in self.units:
            self.setpoint[u] = value
        return Request(0, self._write_single(self.control + 1, round(value * 100)))

    # ---------------------------------------------------------------- PDUs
    def build(self, unit: int, p: PollSpec) -> bytes:
        fc = p.function
        if fc in (0x01, 0x02, 0x03, 0x04):
            return struct.pack(">BHH", fc, p.address, p.count)
        if fc == 0x05:
            self.coil[unit] = not self.coil[unit]
            return struct.pack(">BHH", fc, p.address, 0xFF00 if self.coil[unit] else 0x0000)
        if fc == 0x06:
            return self._write_single(p.address, self._value(unit, p.address))
        if fc == 0x0F:
            nbytes = (p.count + 7) // 8
            bits = self.rng.getrandbits(p.count).to_bytes(nbytes, "little")
            return struct.pack(">BHHB", fc, p.address, p.count, nbytes) + bits
        if fc == 0x10:
            return self._write_multi(unit, p.address, p.count)
        if fc == 0x08:
            return struct.pack(">BHH", fc, 0x0000, self.rng.getrandbits(16))
        return bytes((fc,))  # functions without data (0x11 report server id, 0x07, ...)

    def _value(self, unit: int, addr: int) -> int:
        off = addr - self.control
        if off == 0:
            return self.command_word(unit)
        if off == 1:
            return self.setpoint_word(unit)
        if off in (2, 3):
            return 100  # accel / decel 10.0 s
        return self.rng.getrandbits(16)

    def _write_single(self, addr: int, value: int) -> bytes:
        return struct.pack(">BHH", 0x06, addr, value & 0xFFFF)

    def _write_multi(self, unit: int, addr: int, count: int) -> bytes:
        values = [self._value(unit, addr + i) for i in range(count)]
        return struct.pack(f">BHHB{count}H", 0x10, addr, count, 2 * count, *values)
