"""Scenarios: who is on the simulated bus and how badly it behaves, as data.

Probabilities, unit numbers and register addresses live here, not in the
bus code, so a test can say "the `errors` line" and a benchmark can build a
variant with `dataclasses.replace` instead of patching behaviour.

Timing parameters are in characters where the line's speed should scale
them (turnaround, gaps: what a UART-driven device actually counts) and in
milliseconds where a human configured them (poll period, master timeout).
"""

from __future__ import annotations

from dataclasses import dataclass, field

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


@dataclass(frozen=True, slots=True)
class PollSpec:
    """One request the master sends in its poll cycle.

    Writes take their values from the master's state (see master.py):
    control+0 gets the command word, control+1 the setpoint.
    """

    function: int
    address: int = 0
    count: int = 1
    every: int = 1  # on every N-th cycle ...
    prob: float = 1.0  # ... and then with this probability
    units: tuple[int, ...] = ()  # () = every unit


@dataclass(frozen=True, slots=True)
class Scenario:
    name: str
    units: tuple[UnitSpec, ...]
    polls: tuple[PollSpec, ...]
    drive_map: DriveMap = field(default_factory=DriveMap)
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
    poll_period_ms=0.0,
    gap_chars=(3.5, 4.0),
    timeout_ms=20.0,
    setpoint_change_s=0.2,
    byte_jitter_bits=0.0,
)

SCENARIOS: dict[str, Scenario] = {s.name: s for s in (DEFAULT, ERRORS, FAST, STRESS)}


def get_scenario(name: str) -> Scenario:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}") from None
