"""`sniffer simulate --fault KIND[:UNIT]`: one cause of trouble on the simulated line, as it shows on the wire.

    sc = apply(get_scenario("default"), ["driver_enable_late:2", "bus_unbiased"])
    frames = simulate(sc, sc.line, 30.0, seed=1)      # the bus with those causes in it

Each kind is what `sniffer diagnose` names (sniffer/diagnose); here it is put on the line the way
it happens in a cabinet, so the tests, the demo and the report show it:

* scenario changes (`apply`): unit_silent (the unit never answers), timeout_too_short (a third of
  its answers come 1.1-1.6 master timeouts late: the master retries, the answer arrives alone after
  the retry or collides with it), latency_drift (its turnaround grows through the capture),
  drive_fault (a drive of a real model trips now and then), eeprom_wear (the PLC writes the save
  register every cycle), params_not_saved (the PLC writes a parameter and never saves it; the drive
  loses power half way and comes back with the saved value);
* unit_refuses (BusFaults.refuses): the unit answers every request with exception 02H, in its span;
* what the bus does (`BusFaults`, hooks the bus calls): second_master (a second PLC polls the unit
  on its own schedule: mostly into a quiet line between the first master's exchanges, which waits
  for it, and now and then over the first master's traffic: requests interleave and collide),
  noise_correlated_with_load (interference that grows with the unit's output frequency, as a
  motor cable next to the bus makes it), the power cycle of params_not_saved;
* what the wire carries (wirefaults.py: `wire_faults`, after the bus): frames that overlap in time collide (the
  two drivers' levels AND-ed, read by a UART at the line's settings: uart.py), driver_enable_late
  (the unit's transmitter turns on after its first start bit began), driver_disable_early (it turns
  off before its last stop bit ended), bus_unbiased (no fail-safe bias: the released line floats
  and a receiver reads a character out of it after a transmission now and then);
* what the capture device receives (sources.SimulatedSource): wrong_line_settings (the sniffer set
  to another baud and parity than the line's; KIND:BAUD names the receiver's baud).

A kind that needs a unit takes the scenario's first unit when none is given.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from sniffer.line import LineSettings
from sniffer.simulator.wire import KIND_REQUEST, WireFrame
from sniffer.simulator.scenario import Fault, PollSpec, Scenario


class FaultError(ValueError):
    """A --fault that cannot be applied to the scenario (one line, exit 2)."""


@dataclass(frozen=True)
class FaultKind:
    name: str
    about: str
    unit: bool = True  # takes a unit (KIND:UNIT)
    spans: bool = False  # may come and go (KIND@FROM-TO)
    # (mild, usual, gross) values of the severity number (KIND,SEVERITY; also the words mild and gross),
    # and what the number means; None: the kind has no degrees
    levels: tuple[float, float, float] | None = None
    severity: str = ""


KINDS: dict[str, FaultKind] = {k.name: k for k in (
    FaultKind("driver_enable_late", "the unit's transmitter turns on after its first start bit began", spans=True,
              levels=(0.05, 1.0, 1.0), severity="share of its answers cut"),
    FaultKind("driver_disable_early", "the unit's transmitter turns off before its last stop bit ended", spans=True,
              levels=(0.05, 1.0, 1.0), severity="share of its answers cut"),
    FaultKind("bus_unbiased", "no fail-safe bias: the idle line floats and reads as stray characters", unit=False,
              spans=True, levels=(0.007, 0.6, 0.9), severity="chance of a stray character after a transmission"),
    FaultKind("noise_correlated_with_load", "interference that grows with the unit's output frequency", spans=True,
              levels=(0.05, 0.3, 0.6), severity="share of frames hit at full output frequency"),
    FaultKind("noise_during_ramps", "interference only while the unit's motor accelerates (a fan drive's ramps)",
              spans=True, levels=(0.1, 0.4, 0.8), severity="share of frames hit at the full acceleration"),
    FaultKind("timeout_too_short", "a third of the unit's answers come after the master's timeout",
              levels=(0.05, 0.35, 0.7), severity="share of its answers late"),
    FaultKind("unit_silent", "the unit never answers (KIND@FROM-TO: only then)", spans=True,
              levels=(0.9, 1.0, 1.0), severity="share of the requests it leaves unanswered"),
    FaultKind("params_not_saved", "a parameter is written and never saved; the drive loses power half way"),
    FaultKind("eeprom_wear", "the PLC writes the save register every cycle"),
    FaultKind("drive_fault", "the drive (of a real model) trips every few seconds"),
    FaultKind("wrong_line_settings", "the sniffer is set to another baud and parity than the line "
                                     "(KIND:BAUD: that baud)", unit=False),
    FaultKind("second_master", "a second PLC polls the unit on its own schedule"),
    FaultKind("latency_drift", "the unit's turnaround grows through the capture (KIND@FROM-TO: grows from FROM, "
                               "back to what it was at TO)", spans=True, levels=(0.5, 4.0, 10.0),
              severity="growth of its turnaround per minute, as a share of itself"),
    FaultKind("second_master_blind", "a second PLC polls the unit on its own clock and never listens first: "
                                     "it collides with the first master"),
    FaultKind("second_master_fc04", "a second PLC reads the unit's registers with fc04 (the first master uses fc03)"),
    FaultKind("second_master_polite", "a second PLC polls the unit only when the line is quiet: no collision, "
                                      "but its requests fit no slot of the first master's cycle"),
    FaultKind("unit_refuses", "the unit answers every request with exception 02H (illegal data address), as after "
                              "a mode or firmware change (KIND@FROM-TO: only then)", spans=True),
    FaultKind("timeout_mild", "the unit's slowest answers (about 5 %) come after the master's timeout, "
                              "after its retry"),
)}

SECOND_MASTER_PERIOD_MS = 270.0  # unrelated to any scenario's poll period
M2_LISTENS = 0.6  # share of the second master's requests sent into a quiet line (the rest: when its timer says)
# the second-master kinds: (function it reads with, share of its requests sent into a quiet line)
SECOND_MASTERS: dict[str, tuple[int, float]] = {
    "second_master": (0x03, M2_LISTENS), "second_master_blind": (0x03, 0.0),
    "second_master_fc04": (0x04, M2_LISTENS), "second_master_polite": (0x03, 1.0),
}
MILD_LATE_SHARE = 0.05  # timeout_mild: share of the unit's answers that come after the master's timeout ...
MILD_LATE_TIMEOUTS = (1.02, 1.3)  # ... this many timeouts after the request
MILD_SLOW_SHARE = 0.15  # ... and this share comes slow but in time (0.3-0.95 timeouts): a tail, not a cliff
POWER_OFF_S = 1.5  # params_not_saved: how long the drive is without power
_WORDS = {"mild": 0, "usual": 1, "gross": 2}


def parse(items: Iterable[str] | None) -> tuple[tuple[str, int | None], ...]:
    """`KIND[:UNIT][@FROM-TO][,SEVERITY]` strings -> (kind, unit or None); FaultError for a bad one."""
    return tuple((f.kind, f.unit) for f in parse_faults(items))


def parse_faults(items: Iterable[str] | None) -> tuple[Fault, ...]:
    """`KIND[:UNIT][@FROM-TO][,SEVERITY]` strings -> Faults (the unit None where not given); FaultError for
    an unknown kind, a bad number, a span the kind cannot have or a severity outside 0..1 (a share)."""
    return tuple(_one(item) for item in items or ())


def _one(item: str) -> Fault:
    head, _, sev = item.partition(",")
    head, at, span = head.partition("@")
    kind, sep, arg = head.partition(":")
    kind = kind.strip().replace("-", "_")
    if kind not in KINDS:
        from sniffer.stderr import did_you_mean

        raise FaultError(f"--fault {item!r}: unknown kind; known: {', '.join(KINDS)}{did_you_mean(kind, KINDS)}")
    k = KINDS[kind]
    num = None
    if sep:
        try:
            num = int(arg, 0)
        except ValueError:
            raise FaultError(f"--fault {item!r}: {arg!r} is not a unit number") from None
        if k.unit and not 1 <= num <= 247:
            raise FaultError(f"--fault {item!r}: unit {num} is outside 1..247")
    start, end = 0.0, math.inf
    if at:
        if not k.spans:
            raise FaultError(f"--fault {item!r}: {kind} cannot come and go (no @FROM-TO); those that can: "
                             f"{', '.join(n for n, x in KINDS.items() if x.spans)}")
        a, dash, b = span.partition("-")
        try:
            start, end = float(a or 0), float(b) if b else math.inf
        except ValueError:
            raise FaultError(f"--fault {item!r}: @{span} is not FROM-TO in seconds (e.g. @20-60)") from None
        if not dash or start < 0 or end <= start:
            raise FaultError(f"--fault {item!r}: @{span} is not FROM-TO in seconds with FROM < TO (e.g. @20-60)")
    severity = None
    if sev:
        if k.levels is None:
            raise FaultError(f"--fault {item!r}: {kind} has no degrees (no ,SEVERITY)")
        word = sev.strip().lower()
        try:
            severity = k.levels[_WORDS[word]] if word in _WORDS else float(word)
        except ValueError:
            raise FaultError(f"--fault {item!r}: {sev!r} is not a severity (a number, mild or gross)") from None
        top = math.inf if kind == "latency_drift" else 1.0
        if not 0 < severity <= top:
            raise FaultError(f"--fault {item!r}: severity {severity:g} is outside 0..{top:g} ({k.severity})")
    return Fault(kind, num, start, end, severity)


def level(fault: Fault) -> float:
    """How bad a fault is: its severity, or its kind's usual one."""
    if fault.severity is not None:
        return fault.severity
    levels = KINDS[fault.kind].levels
    return levels[1] if levels else 1.0


def find(sc: Scenario, kind: str) -> tuple[Fault, ...]:
    """The faults of `kind` on the scenario (with their spans and severities): a kind may come twice, on two
    units or in two spans."""
    specs = sc.fault_specs or tuple(Fault(k, u) for k, u in sc.faults)  # (a scenario built with `faults` alone)
    return tuple(f for f in specs if f.kind == kind)


def now(faults: tuple[Fault, ...], t_ns: int, unit: int | None = None) -> Fault | None:
    """The first of `faults` active at `t_ns` (on `unit`, if given), or None."""
    return next((f for f in faults if f.active(t_ns) and (unit is None or f.unit == unit)), None)



def apply(sc: Scenario, items: Iterable[str] | None) -> Scenario:
    """The scenario with the faults `items` name (see the module doc); the faults travel in `sc.faults`
    (kind, unit) and `sc.fault_specs` (with their spans and severities)."""
    faults, specs = [], list(sc.fault_specs)
    for fault in parse_faults(items):
        kind, num = fault.kind, fault.unit
        unit = num if KINDS[kind].unit else None
        if KINDS[kind].unit and unit is None:
            if not sc.units:
                raise FaultError(f"--fault {kind}: scenario {sc.name!r} has no unit")
            unit = sc.units[0].unit
        fault = dataclasses.replace(fault, unit=unit if KINDS[kind].unit else num)
        specs.append(fault)  # (the change sees it last in sc.fault_specs: `_this`)
        sc = _SCENARIO_CHANGES.get(kind, _no_change)(dataclasses.replace(sc, fault_specs=tuple(specs)), unit)
        faults.append((kind, fault.unit))
    if not faults:
        return sc
    return dataclasses.replace(sc, faults=sc.faults + tuple(faults), fault_specs=tuple(specs))


def _this(sc: Scenario) -> Fault:
    """The fault a scenario change is applying (apply puts it last)."""
    return sc.fault_specs[-1]


def receiver_for(sc: Scenario, line: LineSettings) -> LineSettings | None:
    """wrong_line_settings: what the sniffer is set to instead of `line` (None without that fault)."""
    for kind, num in sc.faults:
        if kind == "wrong_line_settings":
            baud = num or (line.baud // 2 if line.baud >= 19200 else line.baud * 2)
            parity = {"N": "E", "E": "N", "O": "E"}[line.parity]
            return LineSettings(baud, parity, 1, line.databits)
    return None


# ------------------------------------------------------------ scenario changes
def _no_change(sc: Scenario, unit: int | None) -> Scenario:
    return sc


def _spec(sc: Scenario, unit: int, what: str):
    for spec in sc.units:
        if spec.unit == unit:
            return spec
    raise FaultError(f"--fault {what}:{unit}: scenario {sc.name!r} has no unit {unit} "
                     f"(units: {', '.join(str(u.unit) for u in sc.units)})")


def _with_unit(sc: Scenario, unit: int, what: str, **changes) -> Scenario:
    spec = _spec(sc, unit, what)
    units = tuple(dataclasses.replace(u, **changes) if u is spec else u for u in sc.units)
    return dataclasses.replace(sc, units=units)


def _model(sc: Scenario, unit: int, what: str, need_save: bool = False):
    from sniffer.simulator.profiles import PROFILES, get_model

    _spec(sc, unit, what)
    model_id = sc.devices.get(unit)
    # a model the simulator has a register-level drive of (a PD-series drive speaks its own framing: no registers)
    models = ("tds-v8",) if need_save else tuple(PROFILES)
    if model_id not in models:
        raise FaultError(f"--fault {what}:{unit}: needs a drive of a real model{' with a save register' * need_save} "
                         f"(--scenario {' or '.join(models)})")
    return get_model(model_id)


def _unit_silent(sc: Scenario, unit: int) -> Scenario:
    fault = _this(sc)
    if any(u.unit == unit for u in sc.units):
        if fault.spanned:
            return sc  # silent only in its span: BusFaults.powered says when
        return _with_unit(sc, unit, "unit_silent", no_answer_prob=level(fault))
    return dataclasses.replace(sc, polls=sc.polls + (PollSpec(0x03, sc.drive_map.monitor, 2, units=(unit,)),))


def _timeout_too_short(sc: Scenario, unit: int) -> Scenario:
    sc = _with_unit(sc, unit, "timeout_too_short", late_prob=level(_this(sc)))
    return dataclasses.replace(sc, retries=max(sc.retries, 1))


def _timeout_mild(sc: Scenario, unit: int) -> Scenario:
    """A unit whose answer time has a long tail: most answers quick, some slow, the slowest 5 % after the
    master's timeout (they come after its retry, which the busy unit does not hear)."""
    char_ms = sc.line.char_ns / 1e6
    slow = (0.3 * sc.timeout_ms / char_ms, 0.95 * sc.timeout_ms / char_ms)
    sc = _with_unit(sc, unit, "timeout_mild", late_prob=MILD_LATE_SHARE, late_timeouts=MILD_LATE_TIMEOUTS,
                    slow_prob=MILD_SLOW_SHARE, slow_turnaround_chars=slow)
    return dataclasses.replace(sc, retries=max(sc.retries, 1))


def _latency_drift(sc: Scenario, unit: int) -> Scenario:
    return _with_unit(sc, unit, "latency_drift", turnaround_growth_per_min=level(_this(sc)))


def _drive_fault(sc: Scenario, unit: int) -> Scenario:
    _model(sc, unit, "drive_fault")
    units = tuple(dataclasses.replace(u, trip_every_s=(4.0, 8.0) if u.unit == unit else (0.0, 0.0))
                  for u in sc.units)
    return dataclasses.replace(sc, units=units)


def _save_address(sc: Scenario, unit: int, what: str) -> tuple[int, int]:
    save = _model(sc, unit, what, need_save=True).eeprom_save
    return save.addr, save.value


def _eeprom_wear(sc: Scenario, unit: int) -> Scenario:
    addr, value = _save_address(sc, unit, "eeprom_wear")
    return dataclasses.replace(sc, polls=sc.polls + (PollSpec(0x06, addr, value=value, units=(unit,)),))


def _params_not_saved(sc: Scenario, unit: int) -> Scenario:
    addr, _ = _save_address(sc, unit, "params_not_saved")
    polls = tuple(p for p in sc.polls if not (p.function == 0x06 and p.address == addr and p.param == ""))
    polls += (PollSpec(0x06, param="An-02", value=3000, every=25, phase=5, units=(unit,)),
              PollSpec(0x03, param="An-02", every=25, phase=17, units=(unit,)))
    return dataclasses.replace(sc, polls=polls)


def _second_master(kind: str):
    """The second PLC polls with Modbus reads: a line of another protocol (PD-series) cannot carry them."""
    def check(sc: Scenario, unit: int) -> Scenario:
        _spec(sc, unit, kind)
        if not sc.protocol.startswith("modbus"):
            raise FaultError(f"--fault {kind}:{unit}: the second master polls with Modbus reads; scenario "
                             f"{sc.name!r} speaks {sc.protocol}")
        return sc
    return check


def _needs_unit(kind: str):
    def check(sc: Scenario, unit: int) -> Scenario:
        _spec(sc, unit, kind)
        return sc
    return check


def _needs_model(kind: str):
    """A kind `diagnose` judges from the drive's decoded values: only on a drive of a real model."""
    def check(sc: Scenario, unit: int) -> Scenario:
        _model(sc, unit, kind)
        return sc
    return check


_SCENARIO_CHANGES = {
    "unit_silent": _unit_silent, "timeout_too_short": _timeout_too_short, "latency_drift": _latency_drift,
    "drive_fault": _drive_fault, "eeprom_wear": _eeprom_wear, "params_not_saved": _params_not_saved,
    "driver_enable_late": _needs_unit("driver_enable_late"),
    "unit_refuses": _needs_unit("unit_refuses"),
    "driver_disable_early": _needs_unit("driver_disable_early"),
    "noise_correlated_with_load": _needs_model("noise_correlated_with_load"),
    "noise_during_ramps": _needs_unit("noise_during_ramps"),
    "timeout_mild": _timeout_mild,
    **{k: _second_master(k) for k in SECOND_MASTERS},
}


# ------------------------------------------------------------ what the bus does
class BusFaults:
    """The faults that change the bus's own behaviour, as hooks its loop calls (sans-I/O, its rng)."""

    def __init__(self, bus) -> None:
        self.bus = bus
        faults = dict(bus.sc.faults)
        self.load = find(bus.sc, "noise_correlated_with_load")
        self.ramps = find(bus.sc, "noise_during_ramps")
        self.silent = [f for f in find(bus.sc, "unit_silent") if f.spanned]
        self.drifts = find(bus.sc, "latency_drift")
        self.refusing = find(bus.sc, "unit_refuses")
        m2 = next((k for k in SECOND_MASTERS if k in faults), None)
        self.m2_unit = faults.get(m2) if m2 is not None else None
        self.m2_function, self.m2_listens = SECOND_MASTERS.get(m2, (0x03, M2_LISTENS))
        self.m2_next = int(bus.sc.start_ms * 1e6) + int(0.4 * SECOND_MASTER_PERIOD_MS * 1e6)
        self._m2_end = 0
        self.free_ns = 0  # the bus time from which the line was quiet before `between` was called (bus.run)
        self.power_unit = faults.get("params_not_saved")
        self.power_off: tuple[int, int] | None = None  # (from, to) in bus time

    def drift_minutes(self, unit: int, now: int) -> float:
        """How long (minutes) the unit's turnaround has been growing: from the capture's start, or from its
        latency_drift span's start while in the span (none outside it: the cause went)."""
        spans = [f for f in self.drifts if f.unit == unit]
        if not spans or not any(f.spanned for f in spans):
            return now / 60e9
        on = next((f for f in spans if f.active(now)), None)
        return 0.0 if on is None else (now - on.start_s * 1e9) / 60e9

    def interference(self, now: int) -> float:
        """Extra chance that a frame is hit: grows with the load unit's output frequency, or with how hard the
        ramps unit accelerates (only while it does), each in its span."""
        extra = 0.0
        for f in self.load:
            drive = self.bus.drives.get(f.unit) if f.active(now) else None
            if drive is not None:
                drive.advance(now)
                top = drive.max_hz() if hasattr(drive, "max_hz") else 60.0
                extra += level(f) * min(1.0, drive.out_hz / top) ** 2
        for f in self.ramps:
            drive = self.bus.drives.get(f.unit) if f.active(now) else None
            if drive is not None:
                drive.advance(now)
                extra += level(f) * min(1.0, max(drive.accel_hz_s, 0.0) / drive.full_accel_hz_s())
        return extra

    def powered(self, unit: int, now: int) -> bool:
        """Whether the unit can answer now: not while it is without power, nor in a span it is silent."""
        off = self.power_off
        if unit == self.power_unit and off is not None and off[0] <= now < off[1]:
            return False
        for f in self.silent:
            if f.unit == unit and f.active(now) and (f.severity is None or self.bus.rng.random() < f.severity):
                return False
        return True

    def refuses(self, unit: int, now: int) -> bool:
        """Whether the unit refuses what it is asked now (unit_refuses, in its span)."""
        return any(f.unit == unit and f.active(now) for f in self.refusing)

    def between(self, now: int, end_ns: int) -> Iterator[WireFrame]:
        """Called between two exchanges: the power loss, and the second master's exchanges that are due."""
        bus = self.bus
        if self.power_unit is not None and self.power_off is None and now >= 0.55 * end_ns:
            self.power_off = (now, now + int(POWER_OFF_S * 1e9))
            bus.drives[self.power_unit].power_cycle()
        if self.m2_unit is None:
            return
        while self.m2_next <= now and self.m2_next < end_ns:
            if self.m2_listens and bus.rng.random() < self.m2_listens:
                # it waits for a quiet line: when its timer says if the line was idle then (the first master
                # between its cycles), else after the first master's exchange; the first master, which also
                # waits for silence before it sends, lets it finish
                t = self.m2_next if self.m2_next >= self.free_ns else now
                yield from self._second_master(t)
                self.free_ns = self._m2_end + bus.line.t35_ns + bus.char
                now = bus.now = max(bus.now, self.free_ns)
            else:  # it sends when its timer says, over whatever is on the line
                yield from self._second_master(self.m2_next)
            self.m2_next += int(SECOND_MASTER_PERIOD_MS * 1e6) + bus.rng.randint(0, 4 * bus.char)

    def _second_master(self, t: int) -> Iterator[WireFrame]:
        """One exchange of the second PLC: a read of two registers of the unit's monitor block (it does not
        listen before it talks: what it sends over the first master's traffic collides in wire_faults)."""
        from sniffer.simulator.master import Request

        bus, unit = self.bus, self.m2_unit
        model = bus.master.models.get(unit)
        first = model.profile.monitor[0] if model is not None else bus.sc.drive_map.monitor
        if self.m2_function == 0x04:  # input registers: the generic drive answers fc04 from address 0
            first = 0
        req = Request(unit, bus.master.build(unit, PollSpec(self.m2_function, first, 2)))
        bus.txn += 1
        adu = bytes((unit,)) + req.pdu
        fr = bus._frame(bus._encode(adu), t, KIND_REQUEST, adu, expects_answer=True, answered=True, txn=bus.txn,
                        role=KIND_REQUEST)
        yield fr
        self._m2_end = fr.t_end_ns
        spec = bus.specs.get(unit)
        drive = bus.drives.get(unit)
        if spec is None or drive is None or not self.powered(unit, t):
            return
        ta = bus._chars(spec.turnaround_chars)
        drive.advance(t)
        payload = bytes((unit,)) + drive.handle(req.pdu)
        rsp = bus._frame(bus._encode(payload), fr.t_end_ns + ta, "response", payload, txn=bus.txn,
                         role="response", turnaround_ns=ta)
        self._m2_end = rsp.t_end_ns
        yield rsp
