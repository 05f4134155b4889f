"""The diagnosis engine: frames in, in capture order; findings out, whenever asked (sans-I/O, no Textual).

    d = Diagnosis(reference=None)
    d.start(info, resolved_by_link, registries)   # a session's settings (what each link was read with)
    for f in frames: d.frame(f)                   # settled, decoded frames; flat memory
    d.findings()                                  # sorted, most severe first; may be asked again later

The engine keeps what every group needs once (`Link`: the line's figures; `Unit`: a unit's requests,
answers, latencies) and hands each frame to the groups (one module each: line, wiring, units, timing,
masters, drives, params, polls), which keep their own bounded counts and turn them into findings.
A unit is only ever blamed on frames that prove it is there: a CRC-good frame naming it, or an answer
paired to a CRC-good request of it; a unit number seen only in damaged frames is a damaged address.
"""

from __future__ import annotations


from sniffer.codes import CRC_UNPROVEN
from sniffer.diagnose.codesets import LATE, RETRY, UART, UNANSWERED
from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.diagnose.finding import Finding, sort
from sniffer.diagnose.state import Group, Link, Unit

RECENT_REQUESTS = 512  # requests remembered (index -> unit, frame, type) for the answers after them
_NONE: frozenset = frozenset()
SLOT_NS = 1_000_000_000  # a damaged burst this soon after a request may be its answer
_ECHO_FUNCTIONS = frozenset((0x05, 0x06, 0x08))  # answered by an echo of the request


class Diagnosis:
    """Frames in, findings out (see the module doc)."""

    def __init__(self, reference=None) -> None:
        from sniffer.diagnose import correlate, drives, line, masters, params, polls, timing, units, when, wiring

        self.t0_ns = 0
        self.links: dict[str, Link] = {}
        self.groups = [line.LineGroup(), wiring.WiringGroup(), units.UnitsGroup(), timing.TimingGroup(),
                       masters.MastersGroup(), drives.DrivesGroup(), correlate.CorrelateGroup(),
                       params.ParamsGroup(reference),
                       polls.PollsGroup()]
        self.when = when.WhenGroup()  # episodes for the findings judged over the whole capture (fill)
        self.groups.append(self.when)
        self._resolved: dict = {}
        self._registries: dict = {}
        # each group's handlers, only where it has one: a frame costs the calls that can use it
        self._requests = _handlers(self.groups, "request")
        self._responses = _handlers(self.groups, "response")
        self._others = _handlers(self.groups, "other")
        self._noise = _handlers(self.groups, "noise")
        self._last: Link | None = None  # the link of the frame before (most captures have one)

    # ------------------------------------------------------------ input
    def start(self, info, resolved=None, registries=None) -> None:
        """A capture starts: its t0, and per link what it was read with (Resolved) and its decoder registry."""
        self.t0_ns = info.t0_ns if info is not None else 0
        self._resolved = dict(resolved or {})
        self._registries = dict(registries or {})

    def start_session(self, session) -> None:
        """start() from an opened capture session (one link or several)."""
        p = getattr(session, "pipeline", None)
        resolved = getattr(p, "resolved", None) or {"": session.resolved}
        registries = getattr(p, "registries", None) or {"": getattr(session, "registry", None)}
        self.start(session.info, resolved, registries)

    def _link(self, name: str) -> Link:
        resolved = self._resolved.get(name) or self._resolved.get("") or next(iter(self._resolved.values()), None)
        registry = self._registries.get(name) or self._registries.get("") or next(iter(self._registries.values()),
                                                                                   None)
        link = self.links[name] = Link(name, resolved, registry)
        return link

    def frame(self, f: Frame) -> None:
        link = self._last
        if link is None or link.name != f.link:
            link = self._last = self.links.get(f.link) or self._link(f.link)
        # each attribute read once: this runs for every frame of the capture
        t, role, ok, noise = f.t_ns, f.role, f.crc_ok, f.protocol == "noise"
        if link.first_ns is None:
            link.first_ns = t
        link.last_ns = f.t_end_ns
        n = len(f.raw)
        link.frames += 1
        link.bytes += n
        codes = frozenset(a.code for a in f.annotations) if f.annotations else _NONE
        gap = f.idle_before_ns
        if gap is None:
            link.gaps_ns += link.t35_ns
        else:
            # an answer's turnaround, and the master's wait before a retry, hold the line; other gaps up to t3.5
            held = role == RESPONSE or codes and role == REQUEST and not RETRY.isdisjoint(codes)
            link.gaps_ns += min(gap, SLOT_NS if held else link.t35_ns)
        due = link.due
        link.slot = None
        if due is not None and role != REQUEST:
            # a damaged burst where an answer is due: the answer of that unit, as the line damaged it
            if (not ok and n >= 4 and t - due[1] < SLOT_NS and f.pair is None
                    and (due[2] is None or abs(n - due[2]) <= 2)):
                link.slot = link.units[due[0]]
                link.slot.garbled += 1
                link.due = None
            elif role == RESPONSE:
                link.due = None
        # damaged: noise, a CRC error, a UART flag (the framer's flags are the annotations whose code says uart)
        link.damage.add(t, noise or ok is False or bool(codes) and not UART.isdisjoint(codes))
        if noise:
            link.noise_frames += 1
            link.noise_bytes += n
            for g in self._noise:
                g(f, link, codes)
            return
        unit = None
        if ok or (codes and CRC_UNPROVEN.code in codes):
            link.matched_bytes += n
        if ok:
            link.good_frames += 1
            link.good_bytes += n
            if f.unit is not None:
                unit = link.units.get(f.unit) or link.unit(f.unit)
                unit.good += 1
        elif ok is False:
            link.crc_bad += 1
        link.last_role = role
        link.last_unit = unit
        if role == REQUEST and ok and unit is not None:
            key = request_type(f)
            self._request(f, link, unit, codes, key)
            for g in self._requests:
                g(f, link, unit, codes, key)
        elif role == RESPONSE:
            got = link.requests.get(f.pair) if f.pair is not None else None
            if got is not None:
                if unit is None or unit.unit != got[0]:
                    unit = link.unit(got[0])
                self._answer(f, link, unit, got[1], codes)
            elif not ok:
                unit = link.slot  # an answer to nothing known, with a damaged address: whoever's answer was due
            for g in self._responses:
                g(f, link, unit, codes, got)
            link.last_unit = unit
            return
        else:
            for g in self._others:
                g(f, link, unit, codes)

    def _request(self, f: Frame, link: Link, u: Unit, codes: frozenset, key: tuple) -> None:
        u.requests += 1
        if u.first_ns is None:
            u.first_ns = f.t_ns
        u.last_ns = f.t_end_ns
        if len(u.frames) < 4:
            u.frames.append(f.index)
        if f.function not in _ECHO_FUNCTIONS:
            u.plain_requests += 1
        if codes:
            if not RETRY.isdisjoint(codes):
                u.retries += 1
            if not UNANSWERED.isdisjoint(codes):
                u.no_response += 1
        link.due = (f.unit, f.t_end_ns, _answer_length(key)) if f.unit != 0 else None
        if f.unit != 0:
            reqs = link.requests
            reqs[f.index] = (f.unit, f, key)
            if len(reqs) > RECENT_REQUESTS:
                reqs.popitem(last=False)

    def _answer(self, f: Frame, link: Link, u: Unit, req: Frame, codes: frozenset) -> None:
        u.answers += 1
        u.last_ns = f.t_end_ns
        if not f.crc_ok:
            u.damaged_answers += 1
            return
        if f.exception:
            u.exceptions += 1
        if f.function in _ECHO_FUNCTIONS and f.raw == req.raw:
            u.echoes += 1
            lat = f.latency_ms
            if lat is not None and lat > 20.0 and u.lat.n >= 5 and lat > 10 * u.typical():
                # far slower than the unit ever answers: the master's retry of its request, not an answer
                link.echo_retries[f.index] = None
                if len(link.echo_retries) > 256:
                    link.echo_retries.popitem(last=False)
            return  # (its latency may be the master's timeout: not the unit's answer time)
        if req.function not in _ECHO_FUNCTIONS:
            u.plain_answers += 1
        if not LATE.isdisjoint(codes):
            u.late += 1
            return
        lat = f.latency_ms
        if lat is not None:
            link.time_sources[f.time_source] = link.time_sources.get(f.time_source, 0) + 1
            if req.annotations and any(a.code in RETRY for a in req.annotations):
                u.answered_retries += 1
                return  # an answer to a retry may be the first try's, late: timing.py judges those
            u.lat.add(lat)
            u.lat_bins.add(f.t_ns, lat)
            if u.first_answer is None:
                u.first_answer = f.index
            u.last_answer = f.index

    # ------------------------------------------------------------ output
    def seconds(self, t_ns: int | None) -> float | None:
        return None if t_ns is None else (t_ns - self.t0_ns) / 1e9

    def findings(self) -> list[Finding]:
        out: list[Finding] = []
        for g in self.groups:
            out += g.findings(self)
        self.when.fill(self, out)
        wrong = {f.link for f in out if f.kind == "wrong_line_settings"}
        if wrong:  # what a link read at the wrong settings shows is noise: nothing else on it is judged
            out = [f for f in out if f.kind == "wrong_line_settings" or f.link not in wrong]
        from sniffer.diagnose.damage import unexplained

        return sort(out + unexplained(out, self))


def request_type(f: Frame) -> tuple:
    """(unit, function, first address, count) of a request: one type of request in a poll cycle
    (address None where the function names none; count 1 for a single write)."""
    adu, fc = f.adu, f.function
    if len(adu) >= 6 and fc in _COUNTED:
        return f.unit, fc, adu[2] << 8 | adu[3], adu[4] << 8 | adu[5]
    if len(adu) >= 4 and fc in (5, 6):
        return f.unit, fc, adu[2] << 8 | adu[3], 1
    return f.unit, fc, None, None


_COUNTED = frozenset((1, 2, 3, 4, 15, 16))


def _answer_length(key: tuple) -> int | None:
    """The length of a good RTU answer to a request of this type (None: not known)."""
    _, fc, _, qty = key
    if fc in (1, 2) and qty:
        return 5 + (qty + 7) // 8
    if fc in (3, 4) and qty:
        return 5 + 2 * qty
    if fc in (5, 6, 8, 15, 16):
        return 8
    return None


def _handlers(groups: list, name: str) -> list:
    return [getattr(g, name) for g in groups if getattr(type(g), name) is not getattr(Group, name)]
