"""The simulated RS-485 line: a PLC master, drive slaves, and what goes wrong.

`simulate()` yields WireFrames in bus order with exact per-byte start times
and the ground truth a test needs to judge a sniffer (what each frame is,
who sent it, whether it was answered, which fault it carries).  It is
sans-I/O and deterministic: one `random.Random(seed)`, integer nanoseconds
of bus time, no wall clock.  Only one party talks at a time, as on a real
half-duplex line, so frames never overlap.  Frames go out in the scenario's
protocol: RTU (ADU + CRC) or ASCII (':' + hex + LRC + CR LF).  The
PD-series protocol (pd-rtu / pd-ascii) has the same checks and wire
encodings but its own PDUs (FUNC LEN DATA): its PLC and inverters are
pd_master.PdMaster and pd_drive.PdDrive, and every frame waits out the
protocol's quiet time (Scenario.quiet_ms).
"""

from __future__ import annotations

import random
from collections.abc import Iterator

from sniffer.framing.crc import crc_bytes, lrc
from sniffer.events import FLAG_FRAMING
from sniffer.line import LineSettings
from sniffer.protocols import PROTOCOLS
from sniffer.simulator.master import Master, Request
from sniffer.simulator.model_drive import ModelDrive
from sniffer.simulator.pd_drive import PdDrive, data_method
from sniffer.simulator.pd_master import PdMaster
from sniffer.simulator.scenario import Scenario, UnitSpec
from sniffer.simulator.drive import Drive
from sniffer.simulator.wire import (  # noqa: F401 - re-exported: the bus's vocabulary
    FAULT_BROADCAST_ANSWER, FAULT_CRC, FAULT_EXCEPTION, FAULT_NOISE, FAULT_TIMEOUT, KIND_BROADCAST, KIND_CORRUPTED,
    KIND_EXCEPTION, KIND_NOISE, KIND_REQUEST, KIND_RESPONSE, KINDS, WireFrame,
)


class _Bus:
    def __init__(self, sc: Scenario, line: LineSettings, seed: int) -> None:
        self.sc = sc
        self.line = line
        self.rng = random.Random(seed)
        self.char = line.char_ns
        self.jitter = int(sc.byte_jitter_bits * 1e9 / line.baud)
        protocol = PROTOCOLS.get(sc.protocol)
        if protocol is None:
            raise ValueError(f"scenario {sc.name}: protocol {sc.protocol!r} is not simulated")
        self.ascii = protocol.text
        self.pd = protocol.family == "pd"
        self.specs: dict[int, UnitSpec] = {u.unit: u for u in sc.units}
        self.drives: dict[int, Drive]
        if self.pd:
            self.master = PdMaster(sc, self.rng)
            method = data_method(self.ascii, line.parity)
            self.drives = {u.unit: PdDrive(u, self.rng, method=method) for u in sc.units}
        else:
            self.master = Master(sc, self.rng)
            self.drives = {
                u.unit: (ModelDrive(u, self.master.models[u.unit], self.rng, sc.protocol)
                         if u.unit in self.master.models else Drive(u, sc.drive_map, self.rng))
                for u in sc.units
            }
        # "more than" the quiet time: one character more, so jitter never eats into it
        self.quiet = int(sc.quiet_ms * 1e6) + self.char if sc.quiet_ms else 0
        # the master's timeout must outlast t3.5, or a retry would glue to its request
        self.timeout = max(int(sc.timeout_ms * 1e6), 2 * line.t35_ns)
        self.txn = 0
        self.now = int(sc.start_ms * 1e6)
        self.busy_until: dict[int, int] = {}  # a unit still working on a late answer ignores requests
        self.plan = None  # the scenario's faults that change what the bus does (faults.BusFaults)
        if sc.faults:
            from sniffer.simulator.faults import BusFaults

            self.plan = BusFaults(self)

    # ---------------------------------------------------------------- wire
    def _encode(self, adu: bytes) -> bytes:
        """An ADU (unit + PDU) as it goes on the wire in the scenario's protocol."""
        if self.ascii:
            return b":" + (adu + bytes((lrc(adu),))).hex().upper().encode() + b"\r\n"
        return adu + crc_bytes(adu)

    def _place(self, raw: bytes, t0: int) -> tuple[tuple[int, ...], int]:
        char = self.char
        if not self.jitter:  # back to back: one range, no loop (a 255-byte frame is 255 start bits)
            times = range(t0, t0 + len(raw) * char, char)
            return tuple(times), times[-1] + char
        times = []
        t = t0
        for _ in raw:
            times.append(t)
            t += self.char + (self.rng.randint(0, self.jitter) if self.jitter else 0)
        return tuple(times), times[-1] + self.char

    def _frame(self, raw: bytes, t0: int, kind: str, adu: bytes = b"", **kw) -> WireFrame:
        times, end = self._place(raw, t0)
        unit = kw.pop("unit", adu[0] if adu else None)
        fn = kw.pop("function", adu[1] if len(adu) > 1 else None)
        return WireFrame(t0, end, raw, times, kind, unit, fn, **kw)

    def _chars(self, lo_hi: tuple[float, float]) -> int:
        return int(self.rng.uniform(*lo_hi) * self.char)

    def _corrupt(self, raw: bytes) -> bytes:
        """Hit one byte: any single-byte error is a burst under 16 bits, so the CRC always catches it.

        ASCII: one hex digit becomes another, which changes one byte of the sum, so the LRC
        always catches it (':' and CR LF are left alone: the frame keeps its shape).
        """
        b = bytearray(raw)
        if self.ascii:
            i = self.rng.randrange(1, len(b) - 2)
            b[i] = self.rng.choice([c for c in b"0123456789ABCDEF" if c != b[i]])
            return bytes(b)
        b[self.rng.randrange(len(b))] ^= self.rng.randint(1, 255)
        return bytes(b)

    # -------------------------------------------------------------- flow
    def run(self, end_ns: int) -> Iterator[WireFrame]:
        sc = self.sc
        period = int(sc.poll_period_ms * 1e6)
        n = 0
        cycle_start = self.now
        plan = self.plan
        while self.now < end_ns:
            if plan is not None:  # the line is quiet from here to the next cycle's start
                plan.free_ns = self.now
            self.now = max(self.now, cycle_start)
            if plan is not None:
                yield from plan.between(self.now, end_ns)
            self.master.operator(self.now)
            if sc.broadcast_every and n % sc.broadcast_every == sc.broadcast_every - 1:
                yield from self._broadcast(self.master.broadcast())
            reqs = self.master.cycle(n)
            for req in reqs:
                if self.now >= end_ns:
                    return
                if plan is not None:
                    plan.free_ns = self.now
                    yield from plan.between(self.now, end_ns)
                yield from self._exchange(req)
                yield from self._idle()
            if not reqs:
                self.now += max(period, 10 * self.char)  # nothing to poll this cycle
            n += 1
            # fixed-rate cycles; an overrun cycle is followed at once, missed slots are skipped
            cycle_start = max(cycle_start + period, self.now)

    def _idle(self) -> Iterator[WireFrame]:
        """The master's pause before its next request, sometimes with noise in it."""
        sc = self.sc
        if sc.noise_prob and self.rng.random() < sc.noise_prob:
            t0 = self.now + max(self.line.t35_ns, self.quiet) + self._chars((1.0, 4.0))
            n = self.rng.randint(*sc.noise_len)
            raw = bytes(self.rng.choice((0x00, 0xFF, self.rng.randrange(256))) for _ in range(n))
            # a 0x00 from a driver switching on is a start bit that never ends: framing error
            flags = tuple((i, FLAG_FRAMING) for i, b in enumerate(raw) if b == 0x00)
            fr = self._frame(raw, t0, KIND_NOISE, fault=FAULT_NOISE, flags=flags)
            yield fr
            self.now = fr.t_end_ns + max(self.line.t35_ns, self.quiet)
        self.now += max(self._chars(sc.gap_chars), self.quiet)

    def _broadcast(self, req: Request) -> Iterator[WireFrame]:
        adu = bytes((0,)) + req.pdu
        self.txn += 1
        liar = next((u for u in self.sc.units if u.answers_broadcast), None)
        fr = self._frame(self._encode(adu), self.now, KIND_BROADCAST, adu, role=KIND_BROADCAST, txn=self.txn,
                         answered=liar is not None)
        yield fr
        for d in self.drives.values():
            d.advance(fr.t_end_ns)
            d.handle(req.pdu)  # every drive applies the write
        self.now = fr.t_end_ns + max(int(self.sc.broadcast_delay_ms * 1e6), self.quiet)
        if liar is not None:
            ta = max(self._chars(liar.turnaround_chars), self.quiet)
            payload = bytes((liar.unit,)) + self.drives[liar.unit].handle(req.pdu)
            rsp = self._frame(self._encode(payload), fr.t_end_ns + ta, KIND_RESPONSE, payload,
                              role=KIND_RESPONSE, txn=self.txn, turnaround_ns=ta,
                              fault=FAULT_BROADCAST_ANSWER)
            yield rsp
            self.now = max(self.now, rsp.t_end_ns)
        yield from self._idle()

    def _exchange(self, req: Request) -> Iterator[WireFrame]:
        """One request, its retries after timeouts, and the reply if any."""
        sc = self.sc
        self.txn += 1
        adu = bytes((req.unit,)) + req.pdu
        raw = self._encode(adu)
        spec = self.specs.get(req.unit)
        plan = self.plan
        late: WireFrame | None = None  # an answer on its way after the master gave up on its request
        late_payload = b""
        for attempt in range(sc.retries + 1):
            extra = plan.interference(self.now) if plan is not None else 0.0
            p_hit = sc.request_corrupt_prob + extra
            hit = p_hit and self.rng.random() < p_hit
            wire = self._corrupt(raw) if hit else raw
            reply = None if hit or spec is None else self._reply(spec, req, raw)
            kind = KIND_CORRUPTED if hit else KIND_REQUEST
            fr = self._frame(
                wire, self.now, kind, unit=req.unit, function=req.pdu[0], expects_answer=True,
                answered=reply is not None, txn=self.txn, attempt=attempt, role=KIND_REQUEST,
                fault=FAULT_CRC if hit else ("" if reply is not None else FAULT_TIMEOUT),
            )
            yield fr
            if late is not None and fr.t_end_ns <= late.t_ns < fr.t_end_ns + self.timeout:
                # the answer to an earlier try comes alone after this one: the master takes it for this
                # one's (the same unit, function and shape) and goes on
                self.now = late.t_end_ns
                self.master.observe(req, late_payload[1:], late.t_end_ns)
                return
            if reply is None:
                self.now = fr.t_end_ns + self.timeout
                continue
            ta, payload, slow = reply
            rsp_raw = self._encode(payload)
            is_exc = bool(payload[1] & 0x80)
            role = KIND_EXCEPTION if is_exc else KIND_RESPONSE
            p_dmg = spec.corrupt_prob + extra
            damaged = p_dmg and self.rng.random() < p_dmg
            fault = FAULT_CRC if damaged else FAULT_EXCEPTION if is_exc else ""
            rsp = self._frame(
                self._corrupt(rsp_raw) if damaged else rsp_raw, fr.t_end_ns + ta,
                KIND_CORRUPTED if damaged else role, payload,
                txn=self.txn, attempt=attempt, role=role, fault=fault,
                # PD-series error replies carry no code byte: the function byte (81H/83H) is the code
                exception_code=(payload[1] if self.pd else payload[2]) if is_exc else None,
                turnaround_ns=ta, late=slow,
            )
            yield rsp
            if ta > self.timeout:  # the master gave up before it came: it tries again, or goes on
                self.busy_until[req.unit] = rsp.t_end_ns
                late, late_payload = (None, b"") if damaged else (rsp, payload)
                self.now = fr.t_end_ns + self.timeout
                continue
            self.now = rsp.t_end_ns
            if not damaged:
                self.master.observe(req, payload[1:], rsp.t_end_ns)
                return
            # the master drops a reply with a bad CRC and waits out its timeout
            self.now = max(self.now + max(self.line.t35_ns, self.quiet), fr.t_end_ns + self.timeout)

    def _reply(self, spec: UnitSpec, req: Request, raw: bytes) -> tuple[int, bytes, bool] | None:
        """(turnaround, response ADU without CRC, slow) or None when the unit stays silent."""
        rng = self.rng
        if spec.no_answer_prob and rng.random() < spec.no_answer_prob:
            return None
        if self.now < self.busy_until.get(spec.unit, 0):
            return None  # still working on a late answer: this request is not heard
        slow = bool(spec.slow_prob) and rng.random() < spec.slow_prob
        ta = max(self._chars(spec.slow_turnaround_chars if slow else spec.turnaround_chars), self.quiet)
        if spec.turnaround_growth_per_min:
            grown = self.plan.drift_minutes(spec.unit, self.now) if self.plan is not None else self.now / 60e9
            ta = int(ta * (1 + spec.turnaround_growth_per_min * grown))
        if spec.late_prob and rng.random() < spec.late_prob:
            ta = int(rng.uniform(*spec.late_timeouts) * self.timeout)  # after the master gave up (a fault)
        else:
            # a reply must start before the master gives up, or the line would collide
            ta = min(ta, self.timeout - self.line.t35_ns)
        drive = self.drives[spec.unit]
        drive.advance(self.now)
        if self.plan is not None and not self.plan.powered(spec.unit, self.now):
            return None
        if self.plan is not None and self.plan.refuses(spec.unit, self.now):
            pdu = bytes((req.pdu[0] | 0x80, 0x02))  # illegal data address: what it no longer has
        elif spec.busy_prob and rng.random() < spec.busy_prob:
            pdu = bytes((req.pdu[0] | 0x80, drive.busy_code))
        else:
            pdu = drive.handle(req.pdu)
        return ta, bytes((spec.unit,)) + pdu, slow


def simulate(scenario: Scenario, line: LineSettings, duration_s: float, seed: int) -> Iterator[WireFrame]:
    """Frames of `duration_s` seconds of bus traffic (exchanges started before the end finish).

    A scenario with `faults` (faults.py) changes what the bus does (BusFaults) and then what the
    wire carries: frames that overlap collide, and line faults reshape bytes (wire_faults)."""
    frames = _Bus(scenario, line, seed).run(int(duration_s * 1e9))
    if scenario.faults:
        from sniffer.simulator.wirefaults import wire_faults

        frames = wire_faults(frames, scenario, line, seed)
    return frames
