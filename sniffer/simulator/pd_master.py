"""The simulated PLC of a PD-series line: what it asks the inverters and when.

Same interface as master.Master (operator / cycle / broadcast / observe), so
the bus (bus.py) runs it unchanged: it decides requests, the bus decides
timing (the protocol's > 50 ms quiet time before every frame, Scenario.quiet_ms).
Requests are FUNC LEN DATA; polls name parameters by the manual's id
("PD174"), status values by the manual's CFG label ("Out F") and control
commands by CNTR bit names ("run+forward"), all resolved through the
decoder's schema.

The program: at start-up it reads the scenario's start-up parameters, writes
the set frequency to PD003 (the drive is stopped: PD003 is not a "**"
parameter, l.335) and starts each drive forward.  Then it polls status every
cycle; now and then the operator changes a set frequency (05H), stops a
drive, starts it forward or reverse, or jogs it.  Every few cycles a
broadcast (unit 0, no reply): a line-wide frequency (05H) or a fault clear
(02H PD172 = 1, which may be written during operation).
"""

from __future__ import annotations

import random
from collections import deque

from decoders.pd_series.schema import PARAMS

from sniffer.simulator.master import Request
from sniffer.simulator.pd_drive import (
    CNTR_BY_NAME, CONTROL, LOOP_TEST, PARAM_BY_ID, READ_PARAM, READ_STATUS, STATUS_BY_LABEL, WRITE_FREQ, WRITE_PARAM,
    param_width, pdu,
)
from sniffer.simulator.scenario import PollSpec, Scenario

# what the operator may do to a drive in each state: (action, weight); an action is a CNTR
# command (COMMANDS: the CNTR bits, the state it leaves the drive in) or "frequency" (05H)
ACTIONS: dict[str, tuple[tuple[str, int], ...]] = {
    "forward": (("frequency", 3), ("stop", 2)),
    "reverse": (("frequency", 2), ("stop", 2)),
    "stopped": (("forward", 3), ("reverse", 2), ("jog", 2)),
    "jog": (("stop", 1),),
}
COMMANDS = {"forward": ("run+forward", "forward"), "reverse": ("run+reverse", "reverse"),
            "stop": ("stop", "stopped"), "jog": ("jog+jog_forward", "jog")}
BROADCASTS = ("frequency", "fault_clear")
FAULT_CLEAR = ("PD172", 1)  # l.286: "01 is for fault clear"; "**": allowed while running


def cntr(names: str) -> int:
    """'run+forward' -> the CNTR byte, by the schema's bit names."""
    return sum(1 << CNTR_BY_NAME[n].bit for n in names.split("+"))


class PdMaster:
    def __init__(self, scenario: Scenario, rng: random.Random) -> None:
        self.sc = scenario
        self.rng = rng
        self.units = [u.unit for u in scenario.units]
        extra = sorted({u for p in scenario.polls for u in p.units} - set(self.units))
        self.targets = self.units + extra
        lo, hi = scenario.setpoint_range_hz
        self.setpoint = {u: round(rng.uniform(max(lo, 10.0), hi) * 2) / 2 for u in self.units}
        self.state = dict.fromkeys(self.units, "stopped")
        self.queue: deque[Request] = deque()
        self.next_change_ns = int(scenario.setpoint_change_s * 1e9)
        self.freq = PARAM_BY_ID["PD003"]
        for u in self.units:
            for p in scenario.startup_polls:
                self.queue.append(Request(u, self.build(u, p)))
            self._command(u, "forward")

    # ------------------------------------------------------------ operator
    def _command(self, unit: int, action: str) -> None:
        bits, self.state[unit] = COMMANDS[action]
        self.queue.append(Request(unit, pdu(CONTROL, bytes((cntr(bits),)))))

    def _frequency(self, unit: int) -> bytes:
        return pdu(WRITE_FREQ, self._freq_word(self.setpoint[unit]))

    def _freq_word(self, hz: float) -> bytes:
        return round(hz / self.freq.scale).to_bytes(2, "big")

    def _new_setpoint(self) -> float:
        lo, hi = self.sc.setpoint_range_hz
        return round(self.rng.uniform(max(lo, 10.0), hi) * 2) / 2

    def operator(self, t_ns: int) -> None:
        if not self.units or t_ns < self.next_change_ns:
            return
        self.next_change_ns = t_ns + int(self.sc.setpoint_change_s * 1e9)
        u = self.rng.choice(self.units)
        choices = ACTIONS[self.state[u]]
        action = self.rng.choices([a for a, _ in choices], [w for _, w in choices])[0]
        if action in ("frequency", "forward", "reverse"):
            self.setpoint[u] = self._new_setpoint()
            self.queue.append(Request(u, self._frequency(u)))
        if action != "frequency":
            self._command(u, action)

    def observe(self, req: Request, reply: bytes, t_ns: int) -> None:
        """The bus hands the PLC each reply; this program acts on none (the drives never trip)."""

    # ------------------------------------------------------------ polling
    def cycle(self, n: int) -> list[Request]:
        """Status polls first (never the function of a broadcast just sent), then the operator's writes."""
        out = []
        for u in self.targets:
            for p in self.sc.polls:
                if p.units and u not in p.units or not p.units and u not in self.units:
                    continue
                if n % p.every != p.phase % p.every or (p.prob < 1.0 and self.rng.random() >= p.prob):
                    continue
                out.append(Request(u, self.build(u, p)))
        out += self.queue
        self.queue.clear()
        return out

    def broadcast(self) -> Request:
        """Unit 0 (l.71): obeyed by every inverter, no reply (l.119)."""
        if self.rng.choice(BROADCASTS) == "frequency":
            hz = self._new_setpoint()
            for u in self.units:
                self.setpoint[u] = hz
            return Request(0, pdu(WRITE_FREQ, self._freq_word(hz)))
        pid, value = FAULT_CLEAR
        return Request(0, self._write(PARAM_BY_ID[pid].number, value))

    # --------------------------------------------------------------- PDUs
    def _number(self, p: PollSpec) -> int:
        """A poll's parameter number or CFG: `param` is a manual id (PD174) or a CFG label (Out F)."""
        if not p.param:
            return p.address
        table = STATUS_BY_LABEL if p.function == READ_STATUS else PARAM_BY_ID
        hit = table.get(p.param)
        if hit is None:
            raise ValueError(f"poll names {p.param!r}, which the PD-series schema does not have")
        return hit.cfg if p.function == READ_STATUS else hit.number

    def _write(self, number: int, value: int) -> bytes:
        return pdu(WRITE_PARAM, bytes((number,)) + value.to_bytes(param_width(PARAMS.get(number)), "big"))

    def build(self, unit: int, p: PollSpec) -> bytes:
        fc = p.function
        if fc == CONTROL:
            return pdu(fc, bytes((cntr(p.param) if p.param else p.value or 0,)))
        if fc == WRITE_FREQ:
            return pdu(fc, self._freq_word(self.setpoint[unit]) if p.value is None else p.value.to_bytes(2, "big"))
        if fc == LOOP_TEST:
            return pdu(fc, self.rng.getrandbits(16).to_bytes(2, "big"))
        number = self._number(p)
        if fc in (READ_PARAM, READ_STATUS):  # two placeholder bytes, as in the l.173 example's LEN=03
            return pdu(fc, bytes((number, 0, 0)))
        if fc == WRITE_PARAM:
            if p.value is not None:
                value = p.value
            elif number == self.freq.number:
                value = round(self.setpoint.get(unit, 0.0) / self.freq.scale)
            else:
                raise ValueError(f"write of PD{number:03d} needs a value")
            return self._write(number, value)
        raise ValueError(f"the simulated PLC has no PD function {fc:02X}H")


__all__ = ["PdMaster", "ACTIONS", "COMMANDS", "cntr"]
