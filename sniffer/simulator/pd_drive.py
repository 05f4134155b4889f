"""A simulated PD-series inverter: its parameters, its status values, its CNTR/CNST logic.

The PD-series protocol (shared/manuals/pd-series-protocol.txt, read by
decoders/pd_series) is not Modbus: a request is FUNC LEN DATA after the
address, LEN counts the bytes after it.  Everything the manual says is read
from the decoder's schema (decoders/pd_series/schema.py), so the simulated
drive and the sniffer share one source: the parameter numbers, access and set
ranges (PARAMS), the CFG selectors and the frequency scale (STATUS), the
CNTR/CNST bit layouts, the error replies 81H/83H.  `PdProfile` holds only what
the manual does not say (how the drive codes the status values without a
scale, its power-up parameter values, which CNTR bit pairs it refuses).

Formats on the wire (see decoders/pd_series/NOTES.md for the readings):
  01H read   ADDR 01 03 PD 00 00  ->  ADDR 01 03 PD HH LL  (LEN=2 + one byte for byte-wide parameters)
  02H write  ADDR 02 03 PD HH LL  ->  echo;  81H 01 PD when refused (l.123-125)
  03H        ADDR 03 01 CNTR      ->  ADDR 03 01 CNST;  83H 01 CNST when the check fails (l.151-153)
  04H        ADDR 04 03 CFG 00 00 ->  ADDR 04 03 CFG HH LL
  05H        ADDR 05 02 HH LL     ->  echo (0.01 Hz)
  08H        ADDR 08 LEN data     ->  echo
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

from decoders.pd_series.schema import CNST_BITS, CNTR_BITS, ERRORS, FUNCTIONS, PARAMS, STATUS, Param

from sniffer.simulator.scenario import DriveMap, UnitSpec
from sniffer.simulator.drive import RPM_PER_HZ, Drive

MODEL = "pd-series"  # the decoder's model id (--device N=pd-series)
STATUS_BY_LABEL = {s.label: s for s in STATUS.values()}
PARAM_BY_ID = {p.id: p for p in PARAMS.values()}
CNTR_BY_NAME = {b.name: b for b in CNTR_BITS}
_FC = {f.name: f.code for f in FUNCTIONS.values()}
READ_PARAM, WRITE_PARAM, CONTROL = _FC["read parameter"], _FC["write parameter"], _FC["control"]
READ_STATUS, WRITE_FREQ, LOOP_TEST = _FC["read status"], _FC["write frequency"], _FC["loop test"]
PARAM_ERROR = next(e.code for e in ERRORS.values() if READ_PARAM in e.answers and WRITE_PARAM in e.answers)
CONTROL_ERROR = next(e.code for e in ERRORS.values() if CONTROL in e.answers)


@dataclass(frozen=True, eq=False)
class PdProfile:
    """What a PD-series drive does that the manual does not print.

    status: CFG label (schema.STATUS) -> (quantity, size of one count).  A
        count of None takes the schema's scale (Set F / Out F: 0.01 Hz, from
        the manual's 30.00 Hz = 0BB8H); the others have no scale in the manual
        (l.167-169), so the sniffer shows them raw and these are our pick.
    params: manual id -> value at power-up (raw); PD165 follows the line.
    refused: CNTR bit pairs the drive answers with 83H ("when the check is
        not correct", l.151): the manual does not say which, contradictions are
        the obvious ones.
    """

    model: str = MODEL
    supply_v: float = 220.0  # single-phase 220 V class: DC bus ~ 311 V
    base_hz: float = 50.0  # PD176 = 0: 50 Hz standard (l.301)
    jog_hz: float = 5.0
    accel_s: float = 5.0  # to base_hz
    counts_per_s_at_base: float = 2.0  # Cont: e.g. parts on a conveyor, proportional to speed
    status: dict[str, tuple[str, float | None]] = field(default_factory=lambda: {
        "Set F": ("set_hz", None), "Out F": ("out_hz", None), "Out A": ("current_a", 0.1),
        "RoTT": ("rpm", 1.0), "DCV": ("dc_bus_v", 0.1), "ACV": ("out_v", 0.1),
        "Cont": ("counter", 1.0), "Tmp": ("temp_c", 1.0),
    })
    params: dict[str, int] = field(default_factory=lambda: {
        "PD170": 0, "PD171": 0, "PD172": 0, "PD175": 0, "PD176": 0,
        "PD177": 0, "PD178": 0, "PD179": 0, "PD180": 0,  # no fault recorded
        "PD181": 105, "PD182": 0x2403, "PD183": 4711,  # raw: the manual gives no encoding
    })
    refused: tuple[tuple[str, str], ...] = (("forward", "reverse"), ("run", "stop"),
                                            ("jog_forward", "jog_reverse"))

    def __post_init__(self) -> None:
        if set(self.status) != set(STATUS_BY_LABEL):
            raise ValueError(f"{self.model}: status must code every CFG of the schema: {sorted(STATUS_BY_LABEL)}")
        for label, (_, count) in self.status.items():
            if (count is None) != (STATUS_BY_LABEL[label].scale is not None):
                raise ValueError(f"{self.model}: {label}: the schema's scale and the profile's count disagree")
        for pid in self.params:
            if pid not in PARAM_BY_ID:
                raise ValueError(f"{self.model}: parameter {pid} is not in the schema")
        for pair in self.refused:
            for name in pair:
                if name not in CNTR_BY_NAME:
                    raise ValueError(f"{self.model}: {name!r} is not a CNTR bit")


PD = PdProfile()
LAST_PARAM = max(PARAMS)  # PD183: the manual's parameters end there; higher numbers do not exist


def param_width(p: Param | None) -> int:
    """Bytes of a parameter's value: one when its set range (or enum) fits a byte (l.107: LEN=2)."""
    if p is None:
        return 2
    top = p.max if p.max is not None else max((v for v, _ in p.enum), default=None)
    return 1 if top is not None and top <= 0xFF else 2


def status_scale(label: str, profile: PdProfile = PD) -> float:
    count = profile.status[label][1]
    return STATUS_BY_LABEL[label].scale if count is None else count


def data_method(ascii_mode: bool, parity: str) -> int | None:
    """PD165's code for the line (l.6-7), from the schema's enum texts."""
    want = f"8{parity}1 for {'ASCII' if ascii_mode else 'RTU'}"
    return next((v for v, text in PARAM_BY_ID["PD165"].enum if text == want), None)


def pdu(fc: int, data: bytes) -> bytes:
    """FUNC LEN DATA: LEN counts the bytes after it (NOTES.md)."""
    return bytes((fc, len(data))) + data


class PdDrive(Drive):
    """One PD-series inverter on the line; the motor physics are the generic drive's."""

    def __init__(self, spec: UnitSpec, rng: random.Random, profile: PdProfile = PD,
                 method: int | None = None) -> None:
        super().__init__(spec, DriveMap(n_params=0, n_coils=0, n_discretes=0), rng)
        self.prof = pr = profile
        self.dc_nominal_v = self.dc_bus_v = pr.supply_v * math.sqrt(2)
        self.accel_01s = self.decel_01s = round(pr.accel_s * 10 * 50.0 / pr.base_hz)
        self.run_cmd = self.jog_cmd = self.reverse = False
        self.counter = 0.0
        self.values: dict[int, int] = {n: 0 for n in range(LAST_PARAM + 1)}
        for pid, v in pr.params.items():
            self.values[PARAM_BY_ID[pid].number] = v
        self.values[PARAM_BY_ID["PD174"].number] = round(spec.rated_current_a)
        if method is not None:
            self.values[PARAM_BY_ID["PD165"].number] = method
        self.freq_param = PARAM_BY_ID["PD003"]

    # ------------------------------------------------------------- physics
    def target_hz(self) -> float:
        if self.jog_cmd:
            return self.prof.jog_hz
        return self.setpoint_hz if self.run_cmd else 0.0

    def advance(self, t_ns: int) -> None:
        before = self.t_ns
        super().advance(t_ns)
        if before is not None:
            dt = max(0, t_ns - before) / 1e9
            self.counter += self.prof.counts_per_s_at_base * self.out_hz / self.prof.base_hz * dt

    def quantity(self, what: str) -> float:
        pr = self.prof
        return {
            "set_hz": self.setpoint_hz,
            "out_hz": self.out_hz,
            "current_a": self.current_a,
            "rpm": self.out_hz * RPM_PER_HZ,
            "dc_bus_v": self.dc_bus_v,
            "out_v": pr.supply_v * min(1.0, self.out_hz / pr.base_hz),  # V/f up to the base frequency
            "counter": self.counter,
            "temp_c": self.temp_c,
        }[what]

    def status_value(self, cfg: int) -> int:
        label = STATUS[cfg].label
        what = self.prof.status[label][0]
        return max(0, min(0xFFFF, int(round(self.quantity(what) / status_scale(label, self.prof)))))

    def cnst(self) -> int:
        moving = self.out_hz > 0.05
        flags = {
            "run": self.run_cmd, "jog": self.jog_cmd, "r_f_command": self.reverse,
            "running": (self.run_cmd or moving) and not self.jog_cmd, "jogging": self.jog_cmd,
            "r_f_running": self.reverse and moving, "braking": self.out_hz > self.target_hz() + 0.05,
            "track_start": False,
        }
        return sum(1 << b.bit for b in CNST_BITS if flags[b.name])

    # ---------------------------------------------------------- protocol
    def handle(self, req: bytes) -> bytes:
        """Answer FUNC LEN DATA with FUNC LEN DATA (also applied for a broadcast, whose reply is dropped)."""
        fc, data = req[0], req[2:]
        if fc == READ_PARAM:
            return self._read(data[0])
        if fc == WRITE_PARAM:
            return self._write(data[0], data[1:], req)
        if fc == CONTROL:
            return self._control(data[0])
        if fc == READ_STATUS:
            cfg = data[0]
            return pdu(fc, bytes((cfg,)) + self.status_value(cfg).to_bytes(2, "big"))
        if fc == WRITE_FREQ:
            self.setpoint_hz = int.from_bytes(data[-2:], "big") * self.freq_param.scale
            return req
        if fc == LOOP_TEST:
            return req
        raise ValueError(f"the simulated PD drive has no function {fc:02X}H")

    def _read(self, number: int) -> bytes:
        if number > LAST_PARAM:
            return pdu(PARAM_ERROR, bytes((number,)))  # l.109-111: "has no this function code"
        if number == self.freq_param.number:
            self.values[number] = round(self.setpoint_hz / self.freq_param.scale)
        width = param_width(PARAMS.get(number))
        return pdu(READ_PARAM, bytes((number,)) + self.values[number].to_bytes(width, "big"))

    def _write(self, number: int, value: bytes, req: bytes) -> bytes:
        p = PARAMS.get(number)
        v = int.from_bytes(value, "big")
        if (number > LAST_PARAM or (p is not None and (p.access == "R" or (p.min is not None and v < p.min)
                                                        or (p.max is not None and v > p.max)))):
            return pdu(PARAM_ERROR, bytes((number,)))  # l.123-125: "the setting is incorrect"
        self.values[number] = v
        if number == self.freq_param.number:
            self.setpoint_hz = v * self.freq_param.scale
        return req

    def _control(self, cntr: int) -> bytes:
        on = {b.name for b in CNTR_BITS if cntr >> b.bit & 1}
        if not on or any(a in on and b in on for a, b in self.prof.refused):
            return pdu(CONTROL_ERROR, bytes((self.cnst(),)))  # l.151-153: present status
        if "stop" in on:
            self.run_cmd = self.jog_cmd = False
        if "forward" in on or "jog_forward" in on:
            self.reverse = False
        if "reverse" in on or "jog_reverse" in on:
            self.reverse = True
        if "r_f" in on:
            self.reverse = not self.reverse
        if on & {"jog", "jog_forward", "jog_reverse"}:
            self.jog_cmd, self.run_cmd = True, False
        if "run" in on:
            self.run_cmd, self.jog_cmd = True, False
        return pdu(CONTROL, bytes((self.cnst(),)))


__all__ = ["PD", "PdDrive", "PdProfile", "MODEL", "LAST_PARAM", "param_width", "status_scale", "pdu",
           "data_method", "STATUS_BY_LABEL", "PARAM_BY_ID", "CNTR_BY_NAME"]
