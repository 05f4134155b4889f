"""A simulated drive: registers that move like a motor's, and its Modbus answers.

The values only need to be plausible enough that a decoder and a human
looking at the TUI see a drive doing something: the output frequency ramps
toward the setpoint, current follows load and acceleration, the DC bus rises
while braking, the heatsink warms up.  `advance()` moves the model to the
time of each request, so values depend on bus time only (deterministic).
"""

from __future__ import annotations

import random
import struct

from sniffer.simulator.scenario import CONTROL_LEN, MONITOR_LEN, DriveMap, UnitSpec

# exception codes
ILLEGAL_FUNCTION = 0x01
ILLEGAL_ADDRESS = 0x02
ILLEGAL_VALUE = 0x03
SLAVE_BUSY = 0x06

MAX_HZ = 60.0
RPM_PER_HZ = 29.4  # 4-pole motor with a little slip


class Drive:
    """Register state of one variable-frequency drive."""

    def __init__(self, spec: UnitSpec, dmap: DriveMap, rng: random.Random) -> None:
        self.spec = spec
        self.map = dmap
        self.rng = rng
        self.cmd = 0  # command word as last written
        self.busy_code = SLAVE_BUSY  # what the drive answers when its CPU is busy
        self.dc_nominal_v = 560.0  # DC bus of a 400 V drive at rest
        self.setpoint_hz = 0.0
        self.out_hz = 0.0
        self.accel_01s = 100  # 10.0 s to 50 Hz
        self.decel_01s = 100
        self.temp_c = 28.0 + rng.random() * 4
        self.dc_bus_v = 560.0
        self.current_a = 0.0
        self.accel_hz_s = 0.0  # how fast the output frequency rose (falls negative) at the last advance
        self.t_ns: int | None = None
        self.coils = [False] * dmap.n_coils
        self.discretes = [rng.random() < 0.3 for _ in range(dmap.n_discretes)]
        self.params = [rng.randrange(0, 1000) for _ in range(dmap.n_params)]

    # ------------------------------------------------------------- physics
    def target_hz(self) -> float:
        return self.setpoint_hz if self.cmd & 1 else 0.0

    def advance(self, t_ns: int) -> None:
        if self.t_ns is None:
            self.t_ns = t_ns
            return
        dt = max(0, t_ns - self.t_ns) / 1e9
        self.t_ns = t_ns
        target = self.target_hz()
        up = 50.0 / max(self.accel_01s / 10, 0.1)
        down = 50.0 / max(self.decel_01s / 10, 0.1)
        before = self.out_hz
        if self.out_hz < target:
            self.out_hz = min(target, self.out_hz + up * dt)
        else:
            self.out_hz = max(target, self.out_hz - down * dt)
        accel = (self.out_hz - before) / dt if dt else 0.0
        if dt:
            self.accel_hz_s = accel
        noise = 1 + (self.rng.random() - 0.5) * 0.04
        if self.out_hz > 0.05:
            load = 0.3 + 0.6 * self.out_hz / 50 + max(accel, 0.0) / up * 0.5
            self.current_a = self.spec.rated_current_a * load * noise
        else:
            self.current_a = 0.0
        regen = max(-accel, 0.0) / down * self.dc_nominal_v * 60.0 / 560.0  # braking pumps the DC bus up
        self.dc_bus_v += (self.dc_nominal_v + regen - self.dc_bus_v) * min(1.0, dt * 5)
        self.dc_bus_v += (self.rng.random() - 0.5) * 2
        heat = 28.0 + 25.0 * self.current_a / self.spec.rated_current_a
        self.temp_c += (heat - self.temp_c) * min(1.0, dt / 60)

    def full_accel_hz_s(self) -> float:
        """How fast the output frequency rises on the set ramp (Hz/s)."""
        return 50.0 / max(self.accel_01s / 10, 0.1)

    def status_word(self) -> int:
        running = self.out_hz > 0.05
        target = self.setpoint_hz if self.cmd & 1 else 0.0
        at_speed = running and abs(self.out_hz - target) < 0.05
        bits = (
            running,
            bool(self.cmd & 2),  # reverse
            at_speed,
            running and self.out_hz < target - 0.05,  # accelerating
            self.out_hz > target + 0.05,  # decelerating
            False, False, False,  # bit7: fault (the simulated drives never trip)
            True,  # bit8: remote control
        )
        return sum(1 << i for i, b in enumerate(bits) if b)

    def monitor(self) -> list[int]:
        target = self.setpoint_hz if self.cmd & 1 else 0.0
        return [
            self.status_word(),
            round(target * 100),
            round(self.out_hz * 100),
            round(self.current_a * 10),
            round(self.dc_bus_v * 10),
            round(min(400.0, 400.0 * self.out_hz / 50) * 10),
            round(self.out_hz * RPM_PER_HZ),
            round(self.temp_c * 10),
        ]

    def control(self) -> list[int]:
        return [self.cmd, round(self.setpoint_hz * 100), self.accel_01s, self.decel_01s]

    # ------------------------------------------------------------ registers
    def read_holding(self, addr: int, count: int) -> list[int] | None:
        m = self.map
        for base, block in (
            (m.control, self.control),
            (m.monitor, self.monitor),
            (m.params, lambda: self.params),
        ):
            words = block()
            if base <= addr and addr + count <= base + len(words):
                return words[addr - base : addr - base + count]
        return None

    def read_input(self, addr: int, count: int) -> list[int] | None:
        m = self.map
        if m.inputs <= addr and addr + count <= m.inputs + MONITOR_LEN:
            return self.monitor()[addr - m.inputs : addr - m.inputs + count]
        return None

    def write_holding(self, addr: int, values: list[int]) -> int | None:
        """Apply a register write; returns an exception code or None."""
        base = self.map.control
        if not (base <= addr and addr + len(values) <= base + CONTROL_LEN):
            return ILLEGAL_ADDRESS
        new = self.control()
        new[addr - base : addr - base + len(values)] = values
        if new[1] > MAX_HZ * 100 or new[2] == 0 or new[3] == 0:
            return ILLEGAL_VALUE
        self.cmd, sp, self.accel_01s, self.decel_01s = new
        self.setpoint_hz = sp / 100
        return None

    # -------------------------------------------------------------- Modbus
    def handle(self, pdu: bytes) -> bytes:
        """Answer a request PDU (function + data) with a response PDU."""
        fc = pdu[0]
        if fc not in self.spec.functions:
            return bytes((fc | 0x80, ILLEGAL_FUNCTION))
        try:
            out = self._dispatch(fc, pdu[1:])
        except (struct.error, IndexError):
            out = ILLEGAL_VALUE
        if isinstance(out, int):
            return bytes((fc | 0x80, out))
        return out

    def _dispatch(self, fc: int, d: bytes) -> bytes | int:
        m = self.map
        if fc in (0x01, 0x02):
            addr, count = struct.unpack(">HH", d[:4])
            bits, base = (self.coils, m.coils) if fc == 0x01 else (self.discretes, m.discretes)
            if not 1 <= count <= 2000:
                return ILLEGAL_VALUE
            if not (base <= addr and addr + count <= base + len(bits)):
                return ILLEGAL_ADDRESS
            if fc == 0x02:
                bits[0] = self.out_hz > 0.05  # input 0 mirrors "running"
            packed = _pack_bits(bits[addr - base : addr - base + count])
            return bytes((fc, len(packed))) + packed
        if fc in (0x03, 0x04):
            addr, count = struct.unpack(">HH", d[:4])
            if not 1 <= count <= 125:
                return ILLEGAL_VALUE
            words = self.read_holding(addr, count) if fc == 0x03 else self.read_input(addr, count)
            if words is None:
                return ILLEGAL_ADDRESS
            return bytes((fc, 2 * count)) + struct.pack(f">{count}H", *(w & 0xFFFF for w in words))
        if fc == 0x05:
            addr, value = struct.unpack(">HH", d[:4])
            if value not in (0x0000, 0xFF00):
                return ILLEGAL_VALUE
            if not m.coils <= addr < m.coils + len(self.coils):
                return ILLEGAL_ADDRESS
            self.coils[addr - m.coils] = value == 0xFF00
            return bytes((fc,)) + d[:4]
        if fc == 0x06:
            addr, value = struct.unpack(">HH", d[:4])
            err = self.write_holding(addr, [value])
            return err if err is not None else bytes((fc,)) + d[:4]
        if fc == 0x0F:
            addr, count, nbytes = struct.unpack(">HHB", d[:5])
            if not 1 <= count <= 1968 or nbytes != (count + 7) // 8:
                return ILLEGAL_VALUE
            if not (m.coils <= addr and addr + count <= m.coils + len(self.coils)):
                return ILLEGAL_ADDRESS
            for i in range(count):
                self.coils[addr - m.coils + i] = bool(d[5 + i // 8] >> (i % 8) & 1)
            return bytes((fc,)) + d[:4]
        if fc == 0x10:
            addr, count, nbytes = struct.unpack(">HHB", d[:5])
            if not 1 <= count <= 123 or nbytes != 2 * count:
                return ILLEGAL_VALUE
            values = list(struct.unpack(f">{count}H", d[5 : 5 + nbytes]))
            err = self.write_holding(addr, values)
            return err if err is not None else bytes((fc,)) + d[:4]
        if fc == 0x08:
            sub = struct.unpack(">H", d[:2])[0]
            if sub != 0x0000:  # only "return query data" is implemented
                return ILLEGAL_FUNCTION
            return bytes((fc,)) + d
        return ILLEGAL_FUNCTION


def _pack_bits(bits: list[bool]) -> bytes:
    out = bytearray((len(bits) + 7) // 8)
    for i, b in enumerate(bits):
        if b:
            out[i // 8] |= 1 << (i % 8)
    return bytes(out)
