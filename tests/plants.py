"""Simulated plants as varied as real ones, seeded: for the sweeps of `sniffer diagnose` (test_diagnose_sweeps.py).

    p = plant(seed)                        # line settings, unit addresses and models, poll cycle: all drawn
    p = with_fault(p, "bus_unbiased", rng) # a cause on it, at a drawn severity and span; p.expect says what
    findings = diagnose(p)                 # the findings `sniffer diagnose` gives on its capture

A plant draws: baud 9600-115200; 8N1, 8E1, 8O1 or 8N2; one to four units at addresses 1-247, each a drive of
a real model (TDS-V8, A510, SPL) or the generic drive; a poll cycle of 50 ms to 2 s; drives started, stopped
and re-set now and then; requests the drives refuse on purpose now and then (a healthy line's exceptions).
The faults are the simulator's (`simulate --fault KIND[:UNIT][@FROM-TO][,SEVERITY]`); each sweep's kind
draws its severity between the limit docs/diagnose.md states and gross.
"""

from __future__ import annotations

import dataclasses
import random
import zlib
from dataclasses import dataclass

from sniffer.diagnose import Diagnosis
from sniffer.line import LineSettings
from sniffer.simulator.faults import apply
from sniffer.simulator.profiles import PROFILES
from sniffer.simulator.scenario import PollSpec, Scenario, UnitSpec
from sniffer.simulator.sources import SimulatedSource

from helpers import diagnose_source

BAUDS = (9600, 19200, 38400, 57600, 115200)
FORMATS = (("N", 1), ("E", 1), ("O", 1), ("N", 2))
CYCLES_MS = (50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0)
MODELS = ("generic", "tds-v8", "a510", "spl")
RESPONSE_MS = {"tds-v8": 5.0, "a510": 10.0, "spl": 10.0}


@dataclass(frozen=True)
class Plant:
    name: str
    scenario: Scenario
    seconds: float
    adapter: str
    seed: int
    faults: tuple[str, ...] = ()
    expect: tuple[tuple[str, int | None], ...] = ()  # (kind, unit) that must be found as error or warning

    @property
    def models(self) -> dict[int, str]:
        return {u.unit: self.scenario.devices.get(u.unit, "generic") for u in self.scenario.units}

    def cycle_s(self) -> float:
        return max(self.scenario.poll_period_ms / 1e3, 0.05)


def plant(seed: int, models: tuple[str, ...] | None = None, cycle_ms: float | None = None,
          busy: bool = False) -> Plant:
    """A healthy plant drawn from `seed` (`models`: the units' models; `busy`: a line polled back to back)."""
    rng = random.Random(seed)
    baud = rng.choice(BAUDS)
    parity, stop = rng.choice(FORMATS)
    line = LineSettings(baud, parity, stop)
    n = len(models) if models else rng.randint(1, 4)
    addresses = sorted(rng.sample(range(1, 248), n))
    models = models or tuple(rng.choice(MODELS) for _ in range(n))
    units, polls, devices = [], [], {}
    for addr, model in zip(addresses, models):
        if model == "generic":
            ta = (2.6, 3.6)
            polls += [PollSpec(0x03, 0x2100, 8, units=(addr,)), PollSpec(0x04, 0x0000, 6, every=4, units=(addr,)),
                      PollSpec(0x10, 0x2000, 2, every=10, units=(addr,))]
        else:
            p = PROFILES[model]
            devices[addr] = model
            chars = RESPONSE_MS[model] * 1e6 / line.char_ns
            ta = (0.9 * chars, 1.1 * chars)
            polls += [PollSpec(0x03, *p.monitor, units=(addr,)), PollSpec(0x03, p.command, 2, every=5, units=(addr,))]
        units.append(UnitSpec(addr, rated_current_a=rng.choice((4.0, 7.5, 12.0, 30.0)), turnaround_chars=ta))
    # exceptions on a healthy line: the PLC probes a register each drive may not have, once at its start (to
    # tell the model), and the first unit is busy now and then
    polls += [PollSpec(0x03, 0x7F00, 1, every=1 << 30, units=(a,)) for a in addresses]
    units[0] = dataclasses.replace(units[0], busy_prob=0.02)
    cycle = 0.0 if busy else (cycle_ms if cycle_ms is not None else rng.choice(CYCLES_MS))
    timeout = max(100.0, 3 * max(RESPONSE_MS.get(m, 2.0) for m in models) + 40 * line.char_ns / 1e6)
    sc = Scenario(f"plant{seed}", tuple(units), tuple(polls), line=line, devices=devices,
                  setpoint_range_hz=(10.0, 50.0), setpoint_change_s=rng.choice((5.0, 20.0, 60.0)),
                  poll_period_ms=cycle, timeout_ms=timeout, gap_chars=(4.0, 6.0) if busy else (4.0, 8.0),
                  fault_reset_s=(0.5, 1.5))
    seconds = max(30.0, 30 * cycle / 1e3)
    return Plant(f"plant{seed} {line.label()} units {dict(zip(addresses, models))} cycle {cycle:g} ms", sc,
                 seconds, rng.choice(("usb", "wire")), seed)


def no_trips(sc: Scenario) -> Scenario:
    return dataclasses.replace(sc, units=tuple(dataclasses.replace(u, trip_every_s=(0.0, 0.0)) for u in sc.units))


def with_fault(p: Plant, fault: str, expect: tuple[tuple[str, int | None], ...], seconds: float | None = None,
               **changes) -> Plant:
    sc = dataclasses.replace(p.scenario, **changes) if changes else p.scenario
    return dataclasses.replace(p, scenario=sc, faults=p.faults + (fault,), expect=p.expect + expect,
                               seconds=seconds or p.seconds, name=f"{p.name} + {fault}")


def diagnose(p: Plant) -> tuple[list, Diagnosis]:
    """The findings of `sniffer diagnose` on the plant's simulated capture (made and read in this process)."""
    sc = apply(p.scenario, list(p.faults))
    return diagnose_source(SimulatedSource(sc, sc.line, p.seconds, p.seed, p.adapter))


def verdict(p: Plant, findings: list) -> tuple[bool, list]:
    """(every expected kind found on its unit, the false alarms: errors and warnings not expected)."""
    worst = [(f.kind, f.unit) for f in findings if f.severity in ("error", "warning")]
    found = all(e in worst for e in p.expect)
    wanted = set(p.expect)
    kinds = {k for k, _ in p.expect}
    # a cause may also be named on the whole line or its other signs (a silent unit's retries): only kinds not
    # expected at all count as false alarms
    also = {c for k in kinds for c in CONSEQUENCES.get(k, ())}
    false = [w for w in worst if w not in wanted and w[0] not in kinds and w[0] not in also]
    return found, false


# what a cause brings with it, named rightly beside it: a silent unit's retries fill the line (and on a line already
# full, stretch its cycle: poll_cycle's warning)
CONSEQUENCES = {"unit_silent": ("retry_storm", "poll_cycle"), "driver_enable_late": ("retry_storm", "poll_cycle"),
                "driver_disable_early": ("retry_storm", "poll_cycle")}


# ------------------------------------------------------------ causes, each at a drawn severity
# kind -> (the models its unit may be, the weakest severity docs/diagnose.md says it finds)
CAUSES: dict[str, tuple[tuple[str, ...], float | None]] = {
    "driver_enable_late": (MODELS, 0.3),
    "driver_disable_early": (MODELS, 0.8),  # a cut shows only where the bits cut were 0 (parity, data bit 7)
    "bus_unbiased": (MODELS, 0.007),
    "noise_correlated_with_load": (("tds-v8", "a510", "spl"), 0.1),
    "noise_during_ramps": (("tds-v8", "a510", "spl"), 0.2),
    "unit_silent": (MODELS, None),
    "drive_fault": (("tds-v8", "a510", "spl"), None),
    "latency_drift": (MODELS, 1.0),
    "eeprom_wear": (("tds-v8",), None),
}
FINDS = {"noise_during_ramps": "noise_correlated_with_load"}  # the simulator's kind -> what diagnose names
MAX_SECONDS = 600.0


def cause(kind: str, seed: int, severity: float | None = None, base: Plant | None = None) -> Plant:
    """A plant with one cause of `kind` on a drawn unit, at `severity` (None: drawn between the kind's limit and
    gross), its span and capture length long enough for the evidence the limit needs."""
    rng = random.Random(seed * 7919 + zlib.crc32(kind.encode()))
    models, limit = CAUSES[kind]
    p = base or plant(seed, models=tuple(rng.choice(models) for _ in range(rng.randint(1, 3))))
    p = dataclasses.replace(p, scenario=no_trips(p.scenario))
    units = [u.unit for u in p.scenario.units if p.models[u.unit] in models]
    if not units:
        p = plant(seed, models=(rng.choice(models),))
        p = dataclasses.replace(p, scenario=no_trips(p.scenario))
        units = [u.unit for u in p.scenario.units]
    unit = rng.choice(units)
    if severity is None and limit is not None:
        severity = rng.uniform(limit, {"latency_drift": 10.0}.get(kind, 1.0 if "driver" in kind else 0.6))
    sev = "" if severity is None else f",{severity:.4g}"
    n_units = len(p.scenario.units)
    tx_per_s = 2 * n_units / max(p.cycle_s(), 0.02)  # transmissions a second, about
    finds = FINDS.get(kind, kind)
    if kind == "bus_unbiased":
        seconds = min(MAX_SECONDS, max(p.seconds, 12 / (severity * tx_per_s)))
        return with_fault(p, f"bus_unbiased{sev}", ((finds, None),), seconds)
    if kind == "unit_silent":
        span = max(10.0, 12 * p.cycle_s())
        seconds = 3 * span
        return with_fault(p, f"unit_silent:{unit}@{span:g}-{2 * span:g}", ((finds, unit),), seconds)
    if kind in ("noise_correlated_with_load", "noise_during_ramps"):
        # (ramps: long enough that each drive ramps on its own, not only all together at the start)
        least = 150.0 if kind == "noise_during_ramps" else 60.0
        seconds = min(MAX_SECONDS, max(p.seconds, least, 400 / tx_per_s / severity))
        return with_fault(p, f"{kind}:{unit}{sev}", ((finds, unit),), seconds,
                          setpoint_change_s=10.0 if kind == "noise_during_ramps" else 10.0)
    if kind == "driver_enable_late" or kind == "driver_disable_early":
        # (enough answers that ~150 are cut: a cut shows only where the bits it takes were 0)
        seconds = min(MAX_SECONDS, max(p.seconds, 150 / (severity / max(p.cycle_s(), 0.02))))
        return with_fault(p, f"{kind}:{unit}{sev}", ((finds, unit),), seconds)
    if kind == "latency_drift":
        seconds = max(p.seconds, 60.0, 150 * p.cycle_s())
        return with_fault(p, f"latency_drift:{unit}{sev}", ((finds, unit),), seconds)
    if kind == "drive_fault":
        sc = dataclasses.replace(p.scenario, units=tuple(
            dataclasses.replace(u, trip_every_s=(4.0, 8.0)) if u.unit == unit else u for u in p.scenario.units))
        p = dataclasses.replace(p, scenario=sc)
        return with_fault(p, f"drive_fault:{unit}", ((finds, unit),), max(p.seconds, 30.0, 10 * p.cycle_s()))
    return with_fault(p, f"{kind}:{unit}", ((finds, unit),))
