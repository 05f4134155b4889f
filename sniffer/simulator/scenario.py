"""Scenarios: who is on the simulated bus and how badly it behaves, as data.

Probabilities, unit numbers and register addresses live here, not in the
bus code, so a test can say "the `errors` line" and a benchmark can build a
variant with `dataclasses.replace` instead of patching behaviour.

Timing parameters are in characters where the line's speed should scale
them (turnaround, gaps: what a UART-driven device actually counts) and in
milliseconds where a human configured them (poll period, master timeout).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sniffer.line import LineSettings
from sniffer.framing.pd import QUIET_NS
from sniffer.simulator.profiles import A510, SPL, TDS_V8, ModelProfile

# Function codes the simulated drives implement; 0x11 (report server id) is
# left out on purpose so a master asking for it draws exception 01.
DRIVE_FUNCTIONS = frozenset({0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x08, 0x0F, 0x10})


@dataclass(frozen=True, slots=True)
class DriveMap:
    """Where a simulated drive keeps its data (a Delta-VFD-like layout).

    control (holding, r/w, 4 words): command word (bit0 run, bit1 reverse,
        bit7 fault reset), frequency setpoint (0.01 Hz), accel time and
        decel time to 50 Hz (0.1 s).
    monitor (holding, read only, 8 words) and inputs (input registers, the
        same 8 words): status word, frequency command (0.01 Hz), output
        frequency (0.01 Hz), output current (0.1 A), DC bus (0.1 V), output
        voltage (0.1 V), motor speed (rpm), heatsink temperature (0.1 C).
    params (holding, read only): a parameter table, big enough for a
        125-register read.
    """

    control: int = 0x2000
    monitor: int = 0x2100
    inputs: int = 0x0000
    params: int = 0x0100
    n_params: int = 128
    coils: int = 0x0000
    n_coils: int = 16
    discretes: int = 0x0000
    n_discretes: int = 16


CONTROL_LEN = 4
MONITOR_LEN = 8


@dataclass(frozen=True, slots=True)
class UnitSpec:
    """One slave on the bus and its habits."""

    unit: int
    rated_current_a: float = 12.0
    # silence between the end of the request and the first response byte;
    # real slaves: 2.6-3.7 characters, i.e. often under t3.5
    turnaround_chars: tuple[float, float] = (2.6, 3.4)
    slow_prob: float = 0.0  # sometimes the slave's CPU is busy and answers late
    slow_turnaround_chars: tuple[float, float] = (5.0, 15.0)
    no_answer_prob: float = 0.0  # request silently lost: the master times out
    busy_prob: float = 0.0  # exception 06 instead of an answer
    corrupt_prob: float = 0.0  # a byte of the response is hit on the wire
    answers_broadcast: bool = False  # firmware bug: replies to unit 0
    functions: frozenset[int] = DRIVE_FUNCTIONS
    # a drive of a real model (Scenario.devices) trips with a fault from its own table after
    # this many seconds of bus time (uniform in the range), again after each reset; (0, 0) = never
    trip_every_s: tuple[float, float] = (0.0, 0.0)
    # answers after the master's timeout now and then (faults.py: timeout_too_short): this share of
    # the answers comes this many master timeouts after the request (no clamp to the timeout)
    late_prob: float = 0.0
    late_timeouts: tuple[float, float] = (1.1, 1.6)
    # the turnaround grows by this share of itself per minute of bus time (faults.py: latency_drift)
    turnaround_growth_per_min: float = 0.0


@dataclass(frozen=True, slots=True)
class PollSpec:
    """One request the master sends in its poll cycle.

    Writes take their values from the master's state (see master.py): the
    unit's command word register gets the command word, its frequency
    register the setpoint (control+0 / control+1 on a generic drive), other
    registers `value`.  `param` names the register by the manual's id
    (e.g. "Cn-27") in the unit's register map instead of by `address`.
    """

    function: int
    address: int = 0
    count: int = 1
    every: int = 1  # on every N-th cycle (cycle % every == phase) ...
    prob: float = 1.0  # ... and then with this probability
    units: tuple[int, ...] = ()  # () = every unit
    phase: int = 0
    value: int | None = None  # the word a write sends (None: from the master's state)
    param: str = ""


@dataclass(frozen=True, slots=True)
class Fault:
    """One cause of trouble put on the line (`simulate --fault KIND[:UNIT][@FROM-TO][,SEVERITY]`, faults.py):
    on a unit (or, for wrong_line_settings, a baud), from one second of bus time to another, this bad
    (None: the kind's usual severity; faults.KINDS says what the number means for each kind)."""

    kind: str
    unit: int | None = None
    start_s: float = 0.0
    end_s: float = math.inf
    severity: float | None = None

    def active(self, t_ns: int) -> bool:
        return self.start_s * 1e9 <= t_ns < self.end_s * 1e9

    @property
    def spanned(self) -> bool:
        return self.start_s > 0.0 or self.end_s != math.inf

    def label(self) -> str:
        """The fault as `--fault` spells it."""
        out = self.kind if self.unit is None else f"{self.kind}:{self.unit}"
        if self.spanned:
            out += f"@{self.start_s:g}-{'' if self.end_s == math.inf else f'{self.end_s:g}'}"
        return out + ("" if self.severity is None else f",{self.severity:g}")


@dataclass(frozen=True, slots=True)
class Scenario:
    name: str
    units: tuple[UnitSpec, ...]
    polls: tuple[PollSpec, ...]
    drive_map: DriveMap = field(default_factory=DriveMap)
    line: LineSettings = LineSettings(19200, "E", 1)  # what a real bus of this kind runs at
    protocol: str = "modbus-rtu"  # or "modbus-ascii", "pd-rtu", "pd-ascii" (PD-series inverters)
    # unit -> model id: those units are drives of that model (profiles.py) and the sniffer
    # decodes them with it; other units are the generic drive (DriveMap)
    devices: dict[int, str] = field(default_factory=dict, hash=False)
    startup_polls: tuple[PollSpec, ...] = ()  # the PLC sends these once per unit before its run command
    fault_reset_s: tuple[float, float] = (0.5, 1.5)  # the PLC resets a tripped drive this long after seeing it
    poll_period_ms: float = 100.0  # a cycle starts this often (at once if the last one overran)
    gap_chars: tuple[float, float] = (4.0, 8.0)  # master's silence before its next request
    timeout_ms: float = 100.0  # master gives up if no response has started by then
    retries: int = 1  # resend the same bytes this often after a timeout
    request_corrupt_prob: float = 0.0  # a request byte is hit on the wire (no slave answers)
    noise_prob: float = 0.0  # per exchange: a noise burst in the idle time after it
    noise_len: tuple[int, int] = (1, 6)
    broadcast_every: int = 0  # every N-th cycle a broadcast setpoint write (0 = never)
    broadcast_delay_ms: float = 30.0  # master's silence after a broadcast (spec: turnaround delay)
    setpoint_change_s: float = 2.0  # the operator changes one drive's setpoint this often
    setpoint_range_hz: tuple[float, float] = (0.0, 50.0)
    byte_jitter_bits: float = 0.1  # extra idle after a character, 0..this many bits
    start_ms: float = 5.0  # idle line before the first frame
    # the protocol's minimum silence before every frame, kept by master and slaves alike
    # (PD-series: "more than 50 ms", l.203-206); 0 = none beyond gap_chars / turnaround_chars
    quiet_ms: float = 0.0
    # causes of trouble on the line (faults.py, `simulate --fault KIND[:UNIT]`): (kind, unit or None)
    faults: tuple[tuple[str, int | None], ...] = ()
    # the same faults with their spans and severities (one Fault each, in the order of `faults`)
    fault_specs: tuple[Fault, ...] = ()


_READS = (
    PollSpec(0x03, 0x2100, 8),  # monitor block, every cycle
    PollSpec(0x03, 0x2000, 4, every=3),  # read back the control block
    PollSpec(0x04, 0x0000, 6, every=4),
    PollSpec(0x01, 0x0000, 16, every=5),
    PollSpec(0x02, 0x0000, 16, every=5),
)
_WRITES = (
    PollSpec(0x10, 0x2000, 2, every=10),  # refresh command word + setpoint
    PollSpec(0x05, 0x0003, 1, every=7, prob=0.5),  # toggle a relay output
    PollSpec(0x0F, 0x0008, 8, every=13, prob=0.5),
    PollSpec(0x08, 0x0000, 1, every=11, prob=0.5),  # diagnostics echo (link check)
)

DEFAULT = Scenario(
    name="default",
    units=(UnitSpec(1), UnitSpec(2, rated_current_a=7.5, turnaround_chars=(2.8, 3.6)), UnitSpec(5)),
    polls=_READS + _WRITES,
)

ERRORS = Scenario(
    name="errors",
    units=(
        UnitSpec(1, no_answer_prob=0.05, corrupt_prob=0.04, slow_prob=0.1),
        UnitSpec(2, busy_prob=0.05, turnaround_chars=(2.5, 3.5)),
        UnitSpec(3, corrupt_prob=0.03, answers_broadcast=True, turnaround_chars=(3.0, 4.0)),
    ),
    polls=_READS
    + _WRITES
    + (
        PollSpec(0x03, 0x3000, 2, every=4, prob=0.5),  # outside the map: exception 02
        PollSpec(0x03, 0x2106, 4, every=6, prob=0.5),  # runs past the monitor block: 02
        PollSpec(0x11, 0, 0, every=9, prob=0.5),  # not implemented: exception 01
        PollSpec(0x03, 0x2100, 2, every=3, units=(9,)),  # unit 9 is not on the bus: timeouts
    ),
    retries=2,
    timeout_ms=60.0,
    request_corrupt_prob=0.02,
    noise_prob=0.05,
    broadcast_every=8,
    setpoint_change_s=1.0,
)

FAST = Scenario(
    name="fast",
    units=(
        UnitSpec(1, turnaround_chars=(2.5, 3.5)),
        UnitSpec(2, turnaround_chars=(2.5, 3.5)),
        UnitSpec(3, turnaround_chars=(2.5, 3.5)),
    ),
    polls=_READS + _WRITES,
    line=LineSettings(115200, "N", 1),
    poll_period_ms=0.0,
    gap_chars=(2.0, 6.0),  # well under the fixed 1.75 ms t3.5 at 115200
    timeout_ms=20.0,
    setpoint_change_s=0.5,
)

STRESS = Scenario(
    name="stress",
    units=tuple(UnitSpec(u, turnaround_chars=(2.0, 3.0)) for u in (1, 2, 3, 4)),
    polls=(
        PollSpec(0x03, 0x2100, 8),
        PollSpec(0x03, 0x0100, 125),  # biggest legal read: 255-byte response
        PollSpec(0x04, 0x0000, 8),
        PollSpec(0x01, 0x0000, 16),
        PollSpec(0x10, 0x2000, 4),
        PollSpec(0x06, 0x2001, 1),
        PollSpec(0x0F, 0x0000, 16),
    ),
    line=LineSettings(115200, "N", 1),
    poll_period_ms=0.0,
    gap_chars=(3.5, 4.0),
    timeout_ms=20.0,
    setpoint_change_s=0.2,
    byte_jitter_bits=0.0,
)


# ------------------------------------------------------------ real drive models
# Two drives of one model on a line the manual allows, the PLC polling the
# model's monitor block and writing its command word and setpoint, plus the
# mistakes a real installation makes now and then, each drawing the model's
# own answer.  Addresses of the monitor and command registers come from the
# profiles (profiles.py); `param` polls name a register by its manual id.
L_ASCII = LineSettings(9600, "E", 1, databits=7)  # Modbus ASCII's usual 7E1


def _turnaround(ms: float, line: LineSettings) -> tuple[float, float]:
    """A response time from the manual, +-10 %, in characters of the line."""
    chars = ms * 1e6 / line.char_ns
    return (0.9 * chars, 1.1 * chars)


def _model_scenario(name: str, p: ModelProfile, line: LineSettings, response_ms: float,
                    polls: tuple[PollSpec, ...], **kw) -> Scenario:
    ta = _turnaround(response_ms, line)
    units = (
        UnitSpec(1, rated_current_a=12.0, turnaround_chars=ta, trip_every_s=(3.0, 7.0)),
        UnitSpec(2, rated_current_a=7.5, turnaround_chars=ta, trip_every_s=(8.0, 20.0)),
    )
    base = (
        PollSpec(0x03, *p.monitor),  # status, fault, frequencies, current, DC bus: every cycle
        PollSpec(0x03, p.command, 2, every=5),  # read back command word + setpoint
        PollSpec(0x08, every=25, phase=3),  # link check (loop-back)
    )
    return Scenario(name, units, base + polls, line=line, devices={u.unit: p.model for u in units},
                    setpoint_range_hz=(10.0, 60.0), **kw)


_TDS_SAVE = 0x0500  # [model] eeprom_save of the TDS-V8 map: write 0 to save An/bn (in DRV mode)
TDS = _model_scenario(
    "tds-v8", TDS_V8,
    LineSettings(9600, "N", 2),  # Sn-37 = 3 (9600, the default), Sn-38 = 0: no parity, 2 stop bits
    5.0,  # "about 5 ms"
    (
        PollSpec(0x03, param="Cn-02", every=100, phase=50),  # max frequency again (scales 0001H/0024H/0025H)
        # a PLC program bug: Cn-27 (communication timeout) written while the drive is in DRV mode
        PollSpec(0x06, param="Cn-27", value=20, every=40, phase=12, units=(1,)),
        # multi-speed 1 = 25.00 Hz (allowed in DRV mode), saved to EEPROM, read back at once:
        # the drive is still saving (21H busy) or the save failed (22H)
        PollSpec(0x06, param="An-01", value=2500, every=20, phase=10, units=(2,)),
        PollSpec(0x06, _TDS_SAVE, value=0, every=20, phase=10, units=(2,)),
        PollSpec(0x03, param="An-01", every=20, phase=10, units=(2,)),
    ),
    startup_polls=(PollSpec(0x03, param="Cn-02"),),  # the sniffer needs Cn-02 to show Hz
    poll_period_ms=200.0,
)

_A510_POLLS = (
    # an HMI asking for the whole monitor block and more: 40 registers, 04H "over 32"
    PollSpec(0x03, A510.monitor[0], 40, every=30, phase=15, units=(2,)),
)
A510_RTU = _model_scenario("a510", A510, LineSettings(19200, "N", 1), 10.0, _A510_POLLS,
                           poll_period_ms=100.0)
A510_ASCII = _model_scenario("a510-ascii", A510, L_ASCII, 10.0, _A510_POLLS, protocol="modbus-ascii",
                             poll_period_ms=300.0)

_SPL_POLLS = (  # an HMI and a commissioning laptop on the same line, each mistake now and then
    PollSpec(0x03, 0x0130, 2, every=40, phase=4, units=(2,)),  # nothing there: 52H
    PollSpec(0x06, SPL.frequency, value=8000, every=40, phase=9, units=(1,)),  # 80.00 Hz > max: 54H
    PollSpec(0x10, 0x0200, 10, value=0, every=40, phase=14, units=(2,)),  # ladder page 1, PLC running: 55H
    PollSpec(0x03, 0x0200, 40, every=40, phase=19, units=(1,)),  # reply over 80 bytes: 53H
    PollSpec(0x04, *SPL.monitor, every=40, phase=24, units=(2,)),  # 04H is not an SPL function: 51H
)
_SPL_KW = dict(timeout_ms=400.0, retries=2)  # "TIME-OUT (400ms) & RETRY (max. : 2 times)"
SPL_RTU = _model_scenario("spl", SPL, LineSettings(9600, "N", 1), 10.0, _SPL_POLLS,  # "10ms" between
                          poll_period_ms=200.0, **_SPL_KW)
SPL_ASCII = _model_scenario("spl-ascii", SPL, L_ASCII, 10.0, _SPL_POLLS, protocol="modbus-ascii",
                            poll_period_ms=300.0, **_SPL_KW)


# ------------------------------------------------------------ PD-series inverters
# Not Modbus (decoders/pd_series): a PLC and two inverters, units 1 and 2, plus broadcasts
# (unit 0).  The manual asks > 50 ms of quiet before every frame (l.203-206), for the master
# and the inverters' replies alike.  Polls name parameters by the manual's id (PD174), status
# values by their CFG label (Out F), control commands by CNTR bit names (pd_master.py).
_PD_QUIET_MS = QUIET_NS / 1e6
_PD_POLLS = (
    PollSpec(0x04, param="Out F"),  # the ramp, every cycle
    PollSpec(0x04, param="Out A", every=2, phase=1),
    PollSpec(0x04, param="Set F", every=4, phase=2),
    PollSpec(0x04, param="DCV", every=4, phase=0),
    PollSpec(0x04, param="RoTT", every=6, phase=3),
    PollSpec(0x04, param="ACV", every=6, phase=5),
    PollSpec(0x04, param="Tmp", every=8, phase=4),
    PollSpec(0x04, param="Cont", every=8, phase=7),
    PollSpec(0x01, param="PD003", every=7, phase=6),  # read back the set frequency
    PollSpec(0x02, param="PD172", value=1, every=11, phase=9, units=(1,)),  # fault clear: "**", allowed running
    PollSpec(0x08, every=9, phase=1),  # loop test
    PollSpec(0x01, param="PD165", every=20, phase=12, units=(1,)),  # data method: says the line
    # mistakes now and then
    PollSpec(0x01, 200, every=10, phase=8, units=(2,)),  # no PD200 (the manual stops at PD183): 81H
    PollSpec(0x02, param="PD170", value=7, every=13, phase=10, units=(1,)),  # set range 0-5: 81H
    PollSpec(0x03, param="forward+reverse", every=12, phase=11, units=(2,)),  # contradictory CNTR: 83H
)
_PD_STARTUP = (PollSpec(0x01, param="PD174"), PollSpec(0x01, param="PD176"), PollSpec(0x01, param="PD181"),
               PollSpec(0x02, param="PD003"))  # rated current, 50/60 Hz, version; set frequency while stopped


def _pd_scenario(name: str, protocol: str, line: LineSettings) -> Scenario:
    quiet = _PD_QUIET_MS
    units = (UnitSpec(1, rated_current_a=7.0, turnaround_chars=_turnaround(quiet * 1.15, line)),
             UnitSpec(2, rated_current_a=4.0, turnaround_chars=_turnaround(quiet * 1.25, line)))
    return Scenario(
        name, units, _PD_POLLS, line=line, protocol=protocol,
        devices={0: "pd-series", **{u.unit: "pd-series" for u in units}},
        startup_polls=_PD_STARTUP, quiet_ms=quiet,
        gap_chars=(1.1 * quiet * 1e6 / line.char_ns, 1.6 * quiet * 1e6 / line.char_ns),
        poll_period_ms=300.0, timeout_ms=500.0, broadcast_every=6, broadcast_delay_ms=quiet,
        setpoint_change_s=1.5, setpoint_range_hz=(10.0, 50.0),
    )


PD_RTU = _pd_scenario("pd-series", "pd-rtu", LineSettings(9600, "N", 1))  # PD165 = 3: 8N1 for RTU
PD_ASCII = _pd_scenario("pd-series-ascii", "pd-ascii", LineSettings(9600, "N", 1))  # PD165 = 0: 8N1 for ASCII

SCENARIOS: dict[str, Scenario] = {
    s.name: s for s in (DEFAULT, ERRORS, FAST, STRESS, TDS, A510_RTU, A510_ASCII, SPL_RTU, SPL_ASCII,
                        PD_RTU, PD_ASCII)
}


def get_scenario(name: str) -> Scenario:
    try:
        return SCENARIOS[name]
    except KeyError:
        from sniffer.stderr import did_you_mean

        raise ValueError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}"
                         f"{did_you_mean(name, SCENARIOS)}") from None
