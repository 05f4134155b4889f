"""The simulated PLC: what it asks for, in which order, with which values.

It decides requests only; the bus (bus.py) decides when they go out and what
happens to them on the wire.  The PLC keeps its own idea of each drive's
command word and setpoint and writes those, the way a real program writes
its tags, so the writes on the line change over time as an operator would
change them.  For a drive of a real model (Scenario.devices) the tags live
where the model's manual says and are coded as its map says (the TDS-V8
setpoint as a fraction of Cn-02); the PLC watches the status word it polls
and resets a tripped drive a little later, as an operator acknowledging the
alarm would.
"""

from __future__ import annotations

import random
import struct
from collections import deque
from dataclasses import dataclass

from sniffer.simulator.profiles import Model, get_model
from sniffer.simulator.scenario import PollSpec, Scenario


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
        self.models: dict[int, Model] = {u: get_model(m) for u, m in scenario.devices.items()}
        lo, hi = scenario.setpoint_range_hz
        self.setpoint = {u: round(rng.uniform(max(lo, 10.0), hi) * 2) / 2 for u in self.units}
        self.run = dict.fromkeys(self.units, True)
        self.coil = dict.fromkeys(self.targets, False)
        self.queue: deque[Request] = deque()  # writes the operator triggered
        self.next_change_ns = int(scenario.setpoint_change_s * 1e9)
        self.tripped: dict[int, int] = {}  # unit -> when the PLC will reset it
        # start-up: what the program reads first, then every drive in run with its setpoint
        for u in self.units:
            for p in scenario.startup_polls:
                self.queue.append(Request(u, self.build(u, p)))
            cmd, freq = self.tag_addresses(u)
            if freq == cmd + 1:
                self.queue.append(Request(u, self._write_multi(u, cmd, 2)))
            else:
                self.queue.append(Request(u, self._write_single(cmd, self.command_word(u))))
                self.queue.append(Request(u, self._write_single(freq, self.setpoint_word(u))))

    def tag_addresses(self, unit: int) -> tuple[int, int]:
        """(command word register, frequency setpoint register) of a unit."""
        m = self.models.get(unit)
        if m is None:
            return self.control, self.control + 1
        return m.profile.command, m.profile.frequency

    def command_word(self, unit: int, reset: bool = False) -> int:
        m = self.models.get(unit)
        if m is None:
            return 0x0001 if self.run.get(unit) else 0x0000
        bits = m.profile.command_bits
        return (bool(self.run.get(unit)) << bits["run"]) | (reset << bits["reset"])

    def setpoint_word(self, unit: int) -> int:
        m = self.models.get(unit)
        hz = self.setpoint.get(unit, 0.0)
        if m is None:
            return round(hz * 100)
        return m.encode(m.profile.frequency, hz, m.params)  # the PLC is set up with the drive's Cn-02

    def observe(self, req: Request, pdu: bytes, t_ns: int) -> None:
        """The PLC reads the reply: a fault bit in a status word it polled schedules a reset."""
        m = self.models.get(req.unit)
        if m is None or pdu[0] != 0x03 or req.pdu[0] != 0x03 or req.unit in self.tripped:
            return
        first, count = struct.unpack(">HH", req.pdu[1:5])
        status = m.profile.status
        if not first <= status < first + count or len(pdu) < 2 + 2 * count:
            return
        word = struct.unpack(">H", pdu[2 + 2 * (status - first) : 4 + 2 * (status - first)])[0]
        if word >> m.profile.status_bits["fault"] & 1:
            self.tripped[req.unit] = t_ns + int(self.rng.uniform(*self.sc.fault_reset_s) * 1e9)

    def operator(self, t_ns: int) -> None:
        """Tripped drives get their reset; now and then someone changes a setpoint (or stops a drive)."""
        for u, due in list(self.tripped.items()):
            if t_ns >= due:
                del self.tripped[u]
                cmd = self.tag_addresses(u)[0]
                self.queue.append(Request(u, self._write_single(cmd, self.command_word(u, reset=True))))
                self.queue.append(Request(u, self._write_single(cmd, self.command_word(u))))  # run again
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
        cmd, freq = self.tag_addresses(u)
        self.queue.append(Request(u, self._write_single(freq, self.setpoint_word(u))))
        if self.run[u] != was_running:
            self.queue.append(Request(u, self._write_single(cmd, self.command_word(u))))

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
                if n % p.every != p.phase % p.every or (p.prob < 1.0 and self.rng.random() >= p.prob):
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
    def address(self, unit: int, p: PollSpec) -> int:
        """A poll's register: `param` is a manual id in the unit's register map."""
        if not p.param:
            return p.address
        m = self.models.get(unit)
        if m is None or p.param not in m.map.by_id:
            raise ValueError(f"poll names {p.param!r}, which unit {unit}'s register map does not have")
        return m.map.by_id[p.param].addr

    def build(self, unit: int, p: PollSpec) -> bytes:
        fc = p.function
        addr = self.address(unit, p)
        if fc in (0x01, 0x02, 0x03, 0x04):
            return struct.pack(">BHH", fc, addr, p.count)
        if fc == 0x05:
            self.coil[unit] = not self.coil[unit]
            return struct.pack(">BHH", fc, addr, 0xFF00 if self.coil[unit] else 0x0000)
        if fc == 0x06:
            return self._write_single(addr, self._value(unit, addr) if p.value is None else p.value)
        if fc == 0x0F:
            nbytes = (p.count + 7) // 8
            bits = self.rng.getrandbits(p.count).to_bytes(nbytes, "little")
            return struct.pack(">BHHB", fc, addr, p.count, nbytes) + bits
        if fc == 0x10:
            return self._write_multi(unit, addr, p.count, p.value)
        if fc == 0x08:
            return struct.pack(">BHH", fc, 0x0000, self.rng.getrandbits(16))
        return bytes((fc,))  # functions without data (0x11 report server id, 0x07, ...)

    def _value(self, unit: int, addr: int) -> int:
        cmd, freq = self.tag_addresses(unit)
        if addr == cmd:
            return self.command_word(unit)
        if addr == freq:
            return self.setpoint_word(unit)
        if unit not in self.models and addr - self.control in (2, 3):
            return 100  # accel / decel 10.0 s
        return self.rng.getrandbits(16)

    def _write_single(self, addr: int, value: int) -> bytes:
        return struct.pack(">BHH", 0x06, addr, value & 0xFFFF)

    def _write_multi(self, unit: int, addr: int, count: int, value: int | None = None) -> bytes:
        values = [self._value(unit, addr + i) if value is None else value for i in range(count)]
        return struct.pack(f">BHHB{count}H", 0x10, addr, count, 2 * count, *values)
