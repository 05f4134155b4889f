"""A simulated drive of a real model: its register map, its faults, its exception codes.

The motor physics are the generic drive's (slave.Drive: ramps, load current,
DC bus); this class puts them where the model's manual says, coded with the
map's scales, and answers requests the way the manual says the model does:
only its function codes, its register limits, its own exception codes
(TDS-V8 21H busy after an EEPROM save, 22H when the save fails; the SPL's
51H-55H; the A510's 04H for more than 32 registers), the DRV/PRG rule where
the map has one.  Now and then it trips with a fault from its own table,
shows it in the status and fault registers, switches its output off and
stays tripped until the PLC writes a fault reset.
"""

from __future__ import annotations

import random
import struct

from sniffer.simulator.profiles import Model, Trip
from sniffer.simulator.scenario import DriveMap, UnitSpec
from sniffer.simulator.drive import ILLEGAL_ADDRESS, ILLEGAL_FUNCTION, ILLEGAL_VALUE, SLAVE_BUSY, Drive

# when a model has no code of its own for a situation, it answers like this one
_FALLBACK = {"read_only": "address", "locked": "address", "frame": "quantity", "quantity": "value",
             "mode": "value", "eeprom": "value"}
_STANDARD = {"function": ILLEGAL_FUNCTION, "address": ILLEGAL_ADDRESS, "value": ILLEGAL_VALUE,
             "busy": SLAVE_BUSY}


class ModelDrive(Drive):
    def __init__(self, spec: UnitSpec, model: Model, rng: random.Random, protocol: str = "modbus-rtu") -> None:
        super().__init__(spec, DriveMap(n_params=0, n_coils=0, n_discretes=0), rng)
        self.model = model
        self.p = p = model.profile
        self.ascii = protocol.endswith("-ascii")
        regs = model.map.registers
        self.valid = {r.addr + k for r in regs.values() for k in range(r.width)}
        self.words: dict[int, int] = {}
        for r in regs.values():
            v = model.params.get(r.addr, r.default if r.default is not None else max(r.min or 0, 0))
            self.words[r.addr] = v & 0xFFFF
        self.busy_code = self.code("busy")
        self.dc_nominal_v = self.dc_bus_v = p.supply_v * 1.35
        self.accel_01s = self.decel_01s = 50  # 5.0 s to 50 Hz
        self.run = False
        self.reverse = False
        self.fault: Trip | None = None
        self.mode = "DRV" if model.mode_register else ""
        self.busy_until_ns = 0
        self.next_trip_ns: int | None = None
        self.saved = dict(self.words)  # what the EEPROM holds: a power cycle comes back with it

    def power_cycle(self) -> None:
        """Power lost and back: the registers are what was last saved, the motor stopped, no trip."""
        self.words = dict(self.saved)
        self.run = False
        self.fault = None
        self.out_hz = self.current_a = 0.0
        self.mode = "DRV" if self.model.mode_register else ""

    def code(self, situation: str) -> int:
        exc = self.p.exceptions
        while situation not in exc and situation in _FALLBACK:
            situation = _FALLBACK[situation]
        return exc.get(situation, _STANDARD.get(situation, ILLEGAL_VALUE))

    # ------------------------------------------------------------- physics
    def max_hz(self) -> float:
        return self.model.max_hz(self.words)

    def target_hz(self) -> float:
        return min(self.setpoint_hz, self.max_hz()) if self.run and self.fault is None else 0.0

    def advance(self, t_ns: int) -> None:
        super().advance(t_ns)
        lo, hi = self.spec.trip_every_s
        if hi <= 0:
            return
        if self.next_trip_ns is None:
            self.next_trip_ns = t_ns + int(self.rng.uniform(lo, hi) * 1e9)
        elif self.fault is None and t_ns >= self.next_trip_ns:
            self.fault = self.rng.choice(self.model.trips)
            self.run = False  # a tripped drive needs a new run command after the reset
            self.out_hz = self.current_a = 0.0  # output stage off: the motor coasts, unseen

    def _reset(self) -> None:
        if self.fault is not None:
            self.fault = None
            lo, hi = self.spec.trip_every_s
            self.next_trip_ns = (self.t_ns or 0) + int(self.rng.uniform(lo, hi) * 1e9)

    # ----------------------------------------------------------- registers
    def status_word(self) -> int:
        running = self.out_hz > 0.05
        target = self.target_hz()
        flags = {
            "run": running,
            "reverse": self.reverse,
            "ready": self.fault is None,
            "fault": self.fault is not None,
            "zero_speed": not running,
            "at_speed": running and abs(self.out_hz - target) < 0.05,
            "class_400v": self.p.supply_v > 300,
        }
        word = sum(1 << bit for name, bit in self.p.status_bits.items() if flags.get(name))
        mr = self.model.mode_register
        if mr and self.mode == "DRV":
            word |= 1 << mr.bit
        return word

    def _measure(self, addr: int, what: str) -> int:
        m = self.model
        fmax = self.max_hz()
        if what in ("freq_cmd", "out_hz"):
            hz = min(self.setpoint_hz, fmax) if what == "freq_cmd" else self.out_hz
            return m.encode(addr, hz, self.words)
        if what == "out_v":
            return m.encode(addr, self.p.supply_v * min(1.0, self.out_hz / fmax), self.words)
        if what == "current":
            return m.encode(addr, self.current_a, self.words)
        if what == "dc_bus":
            return m.encode(addr, self.dc_bus_v, self.words)
        if what == "torque":
            return round(100 * self.current_a / self.spec.rated_current_a)
        if what == "ao_freq":  # 0-10 V or 0-100 % for 0..max frequency
            frac = self.out_hz / fmax
            return m.encode(addr, frac * (10.0 if m.map.registers[addr].unit == "V" else 100.0), self.words)
        if what == "relays":  # relay 1: running, relay 2: fault
            return (self.out_hz > 0.05) | (self.fault is not None) << 1
        raise ValueError(f"unknown quantity {what!r}")

    def word(self, addr: int) -> int:
        p = self.p
        if addr == p.status:
            return self.status_word()
        if addr in p.fault:
            return self.fault.words.get(addr, 0) if self.fault else 0
        what = p.quantities.get(addr)
        if what is not None:
            return self._measure(addr, what) & 0xFFFF
        return self.words.get(addr, 0)

    def _frame_len(self, adu_len: int) -> int:
        return 1 + 2 * (adu_len + 1) + 2 if self.ascii else adu_len + 2

    def read(self, addr: int, count: int) -> list[int] | int:
        """Register words, or an exception code."""
        m = self.model
        if not 1 <= count <= 125:
            return self.code("value")
        if m.max_regs and count > m.max_regs:
            return self.code("quantity")
        if m.max_frame and self._frame_len(3 + 2 * count) > m.max_frame:
            return self.code("frame")
        regs = m.map.registers
        for a in range(addr, addr + count):
            if a not in self.valid or (a in regs and regs[a].access == "W"):
                return self.code("address")
        return [self.word(a) for a in range(addr, addr + count)]

    def write(self, addr: int, values: list[int], block: bool) -> int | None:
        """Apply a register write; returns an exception code or None."""
        m = self.model
        regs = m.map.registers
        for i, v in enumerate(values):
            a = addr + i
            r = regs.get(a)
            if a not in self.valid or r is None:
                return self.code("address")
            if any(lo <= a <= hi for lo, hi in self.p.locked):
                return self.code("locked")
            if r.access == "reserved" and not (block and v == 0):
                return self.code("address")  # a block write may pass over reserved words with 0
            if r.access == "R":
                return self.code("read_only")
            if self.mode == "DRV" and any(lo <= a <= hi for lo, hi in m.prg_only):
                return self.code("mode")
            sv = v - 0x10000 if r.type == "s16" and v >= 0x8000 else v
            if a == self.p.frequency:
                if m.decode(a, v, self.words) > self.max_hz() + 1e-6:
                    return self.code("value")
            elif (r.min is not None and sv < r.min) or (r.max is not None and sv > r.max):
                return self.code("value")
        save = m.eeprom_save
        for i, v in enumerate(values):
            a = addr + i
            if a == self.p.command:
                v = self._command(v)
            elif a == self.p.frequency:
                self.setpoint_hz = m.decode(a, v, self.words)
            elif save and a == save.addr:
                if self.rng.random() < self.p.eeprom_fail_prob:
                    return self.code("eeprom")
                self.busy_until_ns = (self.t_ns or 0) + int(self.p.busy_ms * 1e6)
                self.words[a] = v
                self.saved = dict(self.words)
                continue
            self.words[a] = v
        return None

    def _command(self, v: int) -> int:
        """Act on a command word; returns what reads back (mode bits clear themselves)."""
        bits = self.p.command_bits
        if v >> bits["reset"] & 1:
            self._reset()
        self.run = bool(v >> bits["run"] & 1)
        self.reverse = bool(v >> bits["reverse"] & 1)
        mc = self.model.mode_command
        if mc:
            if v >> mc.to_prg_bit & 1:
                self.mode = "PRG"
            elif v >> mc.to_drv_bit & 1:
                self.mode = "DRV"
            v &= ~(1 << mc.to_prg_bit | 1 << mc.to_drv_bit)
        return v

    # -------------------------------------------------------------- Modbus
    def handle(self, pdu: bytes) -> bytes:
        fc = pdu[0]
        if fc not in self.model.functions:
            return bytes((fc | 0x80, self.code("function")))
        if self.t_ns is not None and self.t_ns < self.busy_until_ns:
            return bytes((fc | 0x80, self.code("busy")))
        try:
            out = self._dispatch(fc, pdu[1:])
        except (struct.error, IndexError):
            out = self.code("value")
        return bytes((fc | 0x80, out)) if isinstance(out, int) else out

    def _dispatch(self, fc: int, d: bytes) -> bytes | int:
        if fc in (0x03, 0x04):
            addr, count = struct.unpack(">HH", d[:4])
            words = self.read(addr, count)
            if isinstance(words, int):
                return words
            return bytes((fc, 2 * count)) + struct.pack(f">{count}H", *words)
        if fc == 0x06:
            addr, value = struct.unpack(">HH", d[:4])
            err = self.write(addr, [value], block=False)
            return err if err is not None else bytes((fc,)) + d[:4]
        if fc == 0x10:
            addr, count, nbytes = struct.unpack(">HHB", d[:5])
            if not 1 <= count <= 123 or nbytes != 2 * count:
                return self.code("value")
            if self.model.max_regs and count > self.model.max_regs:
                return self.code("quantity")
            err = self.write(addr, list(struct.unpack(f">{count}H", d[5 : 5 + nbytes])), block=True)
            return err if err is not None else bytes((fc,)) + d[:4]
        if fc == 0x08:
            if struct.unpack(">H", d[:2])[0] != 0x0000:  # only "return query data"
                return self.code("function")
            return bytes((fc,)) + d
        return self.code("function")
