"""Seeded sweeps of simulated plants for `sniffer diagnose`: one seed draws a line a plant could have (baud,
parity and stop bits, unit addresses 1-247, a unit mix, a poll cycle of 50 ms-2 s, a master timeout), the
faults go on it, and the capture is diagnosed in-process through the engine the command uses.

    plant = draw(seed)                                   # the line's settings, units, cycle
    findings = diagnose_plant(plant, ["second_master_fc04:{u1}"], seconds=60)
    tally([...])                                         # found / missed / false alarms over a sweep

`{u0}`, `{u1}` ... in a fault name the plant's units by position, so one sweep puts a fault on whatever
address the seed drew.  Deterministic for a seed: no clock, no process.
"""

from __future__ import annotations

import dataclasses
import random
from dataclasses import dataclass

from sniffer.line import LineSettings
from sniffer.simulator.faults import apply
from sniffer.simulator.scenario import DEFAULT, PollSpec, UnitSpec
from sniffer.simulator.sources import SimulatedSource

from helpers import diagnose_source

BAUDS = (9600, 19200, 38400, 57600, 115200)
FRAMINGS = (("N", 1), ("E", 1), ("O", 1), ("N", 2))
CYCLES_MS = (50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0)

# a unit mix: what the PLC reads of each unit every cycle (a monitor block), and now and then
_MIXES = (
    (PollSpec(0x03, 0x2100, 8), PollSpec(0x03, 0x2000, 4, every=3), PollSpec(0x06, 0x2001, every=5)),
    (PollSpec(0x03, 0x2100, 4), PollSpec(0x04, 0x0000, 6, every=2), PollSpec(0x10, 0x2000, 2, every=4)),
    (PollSpec(0x03, 0x2100, 6), PollSpec(0x01, 0x0000, 16, every=3)),
)


@dataclass(frozen=True)
class Plant:
    seed: int
    line: LineSettings
    units: tuple[int, ...]
    cycle_ms: float
    timeout_ms: float
    mix: int

    def label(self) -> str:
        return (f"seed {self.seed}: {self.line.label()}, units {','.join(map(str, self.units))}, "
                f"cycle {self.cycle_ms:g} ms, timeout {self.timeout_ms:g} ms, mix {self.mix}")


def draw(seed: int, n_units: tuple[int, int] = (2, 4)) -> Plant:
    """A plant for this seed: settings, addresses and cycle drawn from what real lines use."""
    rng = random.Random(seed)
    parity, stop = rng.choice(FRAMINGS)
    baud = rng.choice(BAUDS)
    units = tuple(sorted(rng.sample(range(1, 248), rng.randint(*n_units))))
    return Plant(seed, LineSettings(baud, parity, stop), units, rng.choice(CYCLES_MS),
                 rng.choice((50.0, 100.0, 200.0)), rng.randrange(len(_MIXES)))


def scenario(plant: Plant, **changes):
    """The plant as a simulator scenario (the default drive map; turnarounds of 2.5-4 characters)."""
    units = tuple(UnitSpec(u, turnaround_chars=(2.5, 4.0)) for u in plant.units)
    fields = {"name": f"sweep{plant.seed}", "units": units, "polls": _MIXES[plant.mix], "line": plant.line,
              "poll_period_ms": plant.cycle_ms, "timeout_ms": plant.timeout_ms}
    return dataclasses.replace(DEFAULT, **{**fields, **changes})


def busy(plant: Plant) -> dict:
    """Scenario changes for a busy but healthy line: cycles back to back (the line 90 % busy and more), the
    drives started and stopped (a new setpoint, 0 Hz among them) every second."""
    return {"poll_period_ms": 0.0, "gap_chars": (3.5, 5.0), "setpoint_change_s": 1.0}


def faults_for(plant: Plant, faults) -> list[str]:
    return [f.format(**{f"u{i}": u for i, u in enumerate(plant.units)}) for f in faults]


def diagnose_plant(plant: Plant, faults=(), seconds: float = 60.0, adapter: str = "wire", **changes):
    """The findings of `seconds` of the plant's line with `faults` on it."""
    sc = apply(scenario(plant, **changes), faults_for(plant, faults))
    return diagnose_source(SimulatedSource(sc, sc.line, seconds, plant.seed, adapter))[0]


def alarms(findings) -> list[tuple[str, int | None]]:
    """(kind, unit) of the findings above info."""
    return [(f.kind, f.unit) for f in findings if f.severity in ("error", "warning")]


def tally(results) -> dict:
    """results: (expected (kind, unit) or None, findings) per run -> found, missed, false alarms (any finding
    above info that is not the expected one)."""
    out = {"runs": 0, "found": 0, "missed": 0, "false_alarms": 0, "missed_runs": [], "false_runs": []}
    for label, want, findings in results:
        got = alarms(findings)
        out["runs"] += 1
        if want is not None:
            if want in got or (want[1] is None and any(k == want[0] for k, _ in got)):
                out["found"] += 1
            else:
                out["missed"] += 1
                out["missed_runs"].append((label, got))
        extra = [g for g in got if want is None or g[0] != want[0]]
        if extra:
            out["false_alarms"] += len(extra)
            out["false_runs"].append((label, extra))
    return out
