"""Pairing on one half-duplex line: which frame is a request, which answers it.

Sans-I/O.  `push(frame)` returns the frames that are settled, in capture
order; a request is held until its response, the next request, a timeout
tick, or the end of the capture settles it (one transaction of delay).

Rules (one master; each has a test of its name in tests/test_pairer.py):
  * pass-through: noise, and a frame the pairer cannot read (no unit or no
    function, or `can` = 0: its shape fits no role) is never paired; it
    keeps its place in capture order and settles nothing;
  * response-only shapes (`can` = CAN_RSP: exception, byte-count shape) are
    responses, request-only shapes (CAN_REQ) requests;
  * a shape that fits both (05/06/08/16 echoes, unknown codes): context
    decides; the response if it matches the pending request's unit and
    function within the response timeout (a 05/06/16 only if it repeats the
    request: another write is the master's next request), else the answer
    to a broadcast just before it (from a unit other than 0), else a new
    request.  Where the two readings mean
    different things (not an echo) and the context is not clear (a response
    whose byte count does not fit the pending request, a request while one
    of the same unit and function is pending, or nothing pending at all),
    pair.role.ambiguous says which was chosen and why;
  * a byte-for-byte copy of a pending 05/06/08/16 request is its echo, unless its timing says it is the
    master's retry (`_a_retry`): it comes later than this unit's (or, not known yet, the line's) recent
    answers by far (RETRY_TURNS times and RETRY_MIN_MS), or about when the master's recent retries came
    (its implied timeout), and not as soon as the unit answers (pair.role.ambiguous says which and why).
    Where the capture knows the direction (a tapped 4-wire link: `can`), the wire decides instead;
  * a new request while one is pending: the pending one is unanswered
    (`_unanswered`: pair.no_response "next request after X ms", and
    pair.timeout when X is past the unit's timeout); identical bytes mark
    the new one pair.retry;
  * a timeout tick past the unit's timeout: the pending request is
    unanswered the same way ("timeout tick after X ms", pair.timeout);
  * end of capture: the pending request gets pair.end_of_capture instead of
    pair.no_response (its answer may simply not have been captured);
  * broadcast (unit 0) expects no answer (pair.broadcast, not held); a
    response right after it is pair.broadcast_response; a Modbus broadcast
    of a function that is not a write is pair.broadcast.function;
  * a response with nothing pending, or for another unit or function, is the
    late answer to a request settled unanswered shortly before (`_late`: the
    same unit and function, and a shape that answers it where both CRCs hold;
    within LATE_WINDOW timeouts; no later request of that unit and function
    that it fits as well, whose own answer it may be): paired to it and flagged pair.late_response
    (the master had moved on: a timeout too short, or a second master's
    request in between); otherwise an orphan (pair.orphan_response).  A
    response whose shape does not answer the pending request but answers such
    an earlier one is that one's late answer too;
  * a response past the unit's timeout is still paired, and flagged
    pair.late_response (no tick settled the request first);
  * a CRC-bad frame whose first byte is the one damage (modbus.crc.one_byte:
    a transmitter that turned on late cuts the address) and whose CRC holds
    with the pending request's unit, of its function, is that request's
    (damaged) response, not a frame of the unit its first byte names;
  * a CRC-bad frame whose length fits no role of its header (modbus.length
    .mismatch: a burst of two transmitters at once, or a frame cut short) is a
    response only if it matches the pending request and starts as its answer
    would (`_answer_head`); never a new request;
  * a CRC-good Modbus response that does not answer its CRC-good request
    (byte count, echo, address) is paired and flagged pair.mismatch
    (`response_mismatch`).
The pairer never raises on a frame a framer can produce: whatever its unit,
function, adu, crc_ok or `can` bits.
"""

from __future__ import annotations

import re

from sniffer import codes
from sniffer.codes import note
from sniffer.events import PER_READ
from sniffer.frame import CAN_REQ, CAN_RSP, REQUEST, RESPONSE, UNKNOWN, Frame
from sniffer.protocols import PROTOCOLS
from collections import deque

from sniffer.framing.crc import damaged_byte
from sniffer.framing.rtu_lengths import BROADCAST_FUNCTIONS, KNOWN_FUNCTIONS

DEFAULT_TIMEOUT_MS = 1000.0
LATE_WINDOW = 3  # an answer is paired to a request settled unanswered at most this many timeouts before it
_RECENT = 8  # requests settled unanswered, kept for their late answers
_CRC16 = frozenset(("modbus-rtu", "pd-rtu"))  # whose frames end in a CRC-16 (crc.damaged_byte)
_MODBUS = frozenset(name for name, p in PROTOCOLS.items() if p.family == "modbus")  # Modbus echo/count rules
_ROLES = CAN_REQ | CAN_RSP
_ECHOES = frozenset((0x05, 0x06, 0x08, 0x16))  # request and response are the same shape and meaning
_WRITE_ECHOES = frozenset((0x05, 0x06, 0x16))  # ... and the response repeats the request byte for byte
# a copy of the pending echo-shaped request this much later than the unit's slowest recent answer (and at least
# RETRY_MIN_MS) is the master's retry; known once TIMING_SEEN answers (or retries) have been seen
RETRY_TURNS = 8
RETRY_MIN_NS = 20_000_000
RETRY_AT_WAIT = 0.8  # ... or this share of the master's shortest recent wait before a retry
TIMING_SEEN = 3


class Pairer:
    def __init__(self, timeout_ms: float = DEFAULT_TIMEOUT_MS, unit_timeouts: dict | None = None) -> None:
        self.timeout_ns = int(timeout_ms * 1e6)
        self.unit_timeouts = {u: int(ms * 1e6) for u, ms in (unit_timeouts or {}).items()}
        self.pending: Frame | None = None
        self.held: list[Frame] = []  # the pending request and what came after it
        self.last_request: Frame | None = None  # for broadcast-response detection
        self.before: int | None = None  # Frame.index of the frame pushed before this one (on this line)
        self._last_index: int | None = None
        self.recent: deque[tuple[Frame, str]] = deque(maxlen=_RECENT)  # (unanswered request, what ended its wait)
        self.latest: dict[tuple[int, int], Frame] = {}  # (unit, function) -> its latest request
        # the timing that tells an echo from the master's retry: recent answer times (per unit and of the line)
        # and the master's waits before a retry, ns (bounded; learned again by a part's warm-up)
        self.turns: dict[int, deque[int]] = {}
        self.line_turns: deque[int] = deque(maxlen=16)
        self.waits: deque[int] = deque(maxlen=8)

    def timeout_for(self, unit: int) -> int:
        """How long a request to `unit` waits for its answer (ns)."""
        return self.unit_timeouts.get(unit, self.timeout_ns)

    def push(self, f: Frame) -> list[Frame]:
        # a line's frames are numbered in a capture-wide sequence when several links share it:
        # "the frame just before" is the one pushed before, not index - 1
        self.before, self._last_index = self._last_index, f.index
        if f.protocol == "noise" or f.function is None or f.unit is None:
            return self._pass_through(f)
        if f.crc_ok is False and self._damaged(f):
            return self._pass_through(f) if f.role != RESPONSE else self._response(f, repaired=True)
        can = f.role_fits
        if can == CAN_RSP:
            f.role = RESPONSE
            return self._response(f)
        if can == CAN_REQ:
            f.role = REQUEST
            return self._request(f)
        if not can & _ROLES:  # fits no role
            return self._pass_through(f)
        pending = self.pending  # the shape fits both: context decides
        if pending is not None and _same_transaction(pending, f):
            if (f.function in _WRITE_ECHOES and f.crc_ok and pending.crc_ok and f.adu != pending.adu
                    and f.protocol in _MODBUS):
                # an echo repeats its request byte for byte: another write is the master's next request
                f.annotations.append(note(
                    codes.ROLE_AMBIGUOUS, f"not an echo of #{pending.index}: taken as a new request (as its "
                                          f"response it would be a mismatched echo)", 0, len(f.raw)))
            elif (f.function in _ECHOES and f.raw == pending.raw and f.protocol in _MODBUS
                  and (why := self._a_retry(pending, f)) is not None):
                f.annotations.append(note(codes.ROLE_AMBIGUOUS, f"taken as the master's retry of #{pending.index}: "
                                                                f"{why}", 0, len(f.raw)))
            elif f.t_ns - pending.t_end_ns <= self.timeout_for(pending.unit):
                if f.function not in _ECHOES and f.protocol in _MODBUS and pending.crc_ok and f.crc_ok:
                    why = response_mismatch(pending.adu, f.adu)
                    if why:
                        f.annotations.append(note(
                            codes.ROLE_AMBIGUOUS,
                            f"taken as the response to #{pending.index} though {why}; as a request it "
                            f"would leave #{pending.index} unanswered", 0, len(f.raw)))
                f.role = RESPONSE
                return self._response(f)
            if f.function not in _ECHOES and f.protocol in _MODBUS:
                f.annotations.append(note(
                    codes.ROLE_AMBIGUOUS,
                    f"taken as a new request: #{pending.index} waited past the unit's timeout", 0, len(f.raw)))
        if pending is None and self._answers_broadcast(f):
            f.role = RESPONSE
            return self._response(f)
        if (pending is None and f.protocol in _MODBUS and f.function in KNOWN_FUNCTIONS
                and f.function not in _ECHOES):
            f.annotations.append(note(codes.ROLE_AMBIGUOUS, "fits a request and a response; nothing pending, "
                                                            "so taken as a request", 0, len(f.raw)))
        f.role = REQUEST
        return self._request(f)

    def _a_retry(self, req: Frame, f: Frame) -> str | None:
        """Why a byte-for-byte copy of the pending echo-shaped request is the master's retry, not the unit's
        echo (None: taken as the echo).  Only timing tells them apart on a half-duplex line: an echo comes as
        soon as the unit answers, a retry when the master's timer runs out."""
        if f.time_source == "none" or not (f.crc_ok and req.crc_ok):
            return None
        lat = f.t_ns - req.t_end_ns
        mine = self.turns.get(req.unit)
        seen = mine if mine is not None and len(mine) >= TIMING_SEEN else (
            self.line_turns if len(self.line_turns) >= TIMING_SEEN else None)
        turn = max(seen) if seen is not None else None
        wait = min(self.waits) if len(self.waits) >= 2 else None
        # (the words name no learned figure: a part decoded alone learns them again, and says the same)
        if (wait is not None and lat >= RETRY_AT_WAIT * wait and (turn is None or lat > 2 * turn)
                or wait is None and turn is not None and lat > max(RETRY_TURNS * turn, RETRY_MIN_NS)):
            return (f"{lat / 1e6:.1f} ms after it, far later than the answers on this line come and when the "
                    f"master's timer runs out (an echo comes as soon as the unit answers)")
        return None

    def _timing(self, req: Frame, f: Frame, lat: int) -> None:
        """An answer in time to a request that is not echo-shaped: how soon the unit (and the line) answers."""
        if lat <= 0 or f.time_source == "none" or f.function in _ECHOES or not f.crc_ok or f.function & 0x80:
            return
        mine = self.turns.get(req.unit)
        if mine is None:
            mine = self.turns[req.unit] = deque(maxlen=8)
        mine.append(lat)
        self.line_turns.append(lat)

    def _damaged(self, f: Frame) -> bool:
        """A CRC-bad frame the bytes say more about: the pending request's response with its address cut
        (role set to RESPONSE: True), or a length that fits no role, which is no request (True: passed through
        unless it answers the pending request).  False: the ordinary rules decide."""
        req = self.pending
        fn = f.function
        answers = req is not None and (fn == req.function or fn == req.function | 0x80)
        if answers and f.unit != req.unit and f.protocol in _CRC16:
            hit = damaged_byte(f.raw)
            if hit is not None and hit == (0, req.unit):
                f.role = RESPONSE
                return True
        if any(a.code == codes.LENGTH_MISMATCH.code for a in f.annotations):
            if answers and f.unit == req.unit and f.role_fits & CAN_RSP and _answer_head(req.adu, f.raw):
                f.role = RESPONSE
            return True
        return False

    def _pass_through(self, f: Frame) -> list[Frame]:
        """Not paired: settled now, or held behind the pending request to keep capture order."""
        if self.held:
            self.held.append(f)
            return []
        return [f]

    def _answers_broadcast(self, f: Frame) -> bool:
        """A unit's echo of the broadcast write just before it (a bug to flag, not a new request)."""
        last = self.last_request
        if (last is None or last.unit != 0 or last.function != f.function or last.index != self.before
                or f.unit == 0):  # unit 0 again: the master repeating its broadcast, not an answer
            return False
        if f.function in (0x05, 0x06, 0x16):
            return f.adu[2:] == last.adu[2:]
        if f.function in (0x0F, 0x10):
            return len(f.adu) == 6 and f.adu[2:6] == last.adu[2:6]
        return True

    def _response(self, f: Frame, repaired: bool = False) -> list[Frame]:
        req = self.pending
        if req is not None and (req.unit == f.unit or repaired) and (
                f.function == req.function or f.function == req.function | 0x80):
            if self.recent and req.crc_ok and f.crc_ok and f.protocol in _MODBUS \
                    and response_mismatch(req.adu, f.adu) and self._late(f, shape_only=True):
                return self._pass_through(f)  # answers an earlier request, not this one: that one's late answer
            self.pending = None  # (_same_transaction, inline: every response passes here)
            f.pair = req.index if req.index >= 0 else None  # (< 0: a request of the part before)
            req.pair = f.index
            f.peer = req
            req.peer = f
            lat = f.t_ns - req.t_end_ns
            # per-read times are estimated back from the read: a response read together
            # with its request has no measurable turnaround (latency stays null; the
            # frame's time_source "read" says why)
            # frames typed in (`sniffer decode`, time source "none") have no time to measure
            if f.time_source != "none" and not (f.time_source in PER_READ and lat <= 0):
                # to the microsecond, as the frame record has it: a viewer that reads the record and
                # one that has the frame show the same figure (rounding twice could differ)
                f.latency_ms = round(lat / 1e6, 3)
            if lat > self.unit_timeouts.get(req.unit, self.timeout_ns) and f.time_source != "none":
                f.annotations.append(
                    note(codes.LATE_RESPONSE, f"{lat / 1e6:.1f} ms after the request", 0, len(f.raw))
                )
            elif not (f.time_source in PER_READ and lat <= 0):
                self._timing(req, f, lat)
            why = (response_mismatch(req.adu, f.adu)
                   if req.crc_ok and f.crc_ok and f.protocol in _MODBUS else None)
            if why:
                f.annotations.append(note(codes.PAIR_MISMATCH, why, 0, len(f.raw)))
            out = self.held  # the request and anything held since: settled now
            out.append(f)
            self.held = []
            return out
        last = self.last_request
        if req is None and last is not None and last.unit == 0 and last.index == self.before:
            f.annotations.append(
                note(codes.BROADCAST_RESPONSE, f"unit {f.unit} answered broadcast frame #{last.index}",
                     0, len(f.raw))
            )
        elif not self._late(f):
            why = "nothing pending" if req is None else (
                f"pending request #{req.index} is for unit {req.unit} function 0x{req.function:02X}"
            )
            f.annotations.append(note(codes.ORPHAN_RESPONSE, why, 0, len(f.raw)))
        return self._pass_through(f)

    def _late(self, f: Frame, shape_only: bool = False) -> bool:
        """Pair `f` to the request it answers among those settled unanswered shortly before (the latest
        first): the same unit and function, and where both CRCs hold a shape that answers it.  True if paired
        (flagged pair.late_response, its latency from that request)."""
        for k in range(len(self.recent) - 1, -1, -1):
            req, ended = self.recent[k]
            if req.unit != f.unit or not (f.function == req.function or f.function == req.function | 0x80):
                continue
            if f.t_ns - req.t_end_ns > LATE_WINDOW * self.timeout_for(req.unit):
                continue
            if req.crc_ok and f.crc_ok and f.protocol in _MODBUS and response_mismatch(req.adu, f.adu):
                continue
            if shape_only and not (req.crc_ok and f.crc_ok):
                return False
            newer = self.latest.get((req.unit, req.function))
            if newer is not None and newer is not req and not (
                    newer.crc_ok and f.crc_ok and f.protocol in _MODBUS and response_mismatch(newer.adu, f.adu)):
                return False  # a later request of the unit (answered, or its answer lost) fits it as well
            del self.recent[k]
            f.role = RESPONSE
            f.pair = req.index if req.index >= 0 else None
            f.peer = req  # decoded with its request (which was settled and decoded before it)
            lat = f.t_ns - req.t_end_ns
            if f.time_source != "none":
                f.latency_ms = round(lat / 1e6, 3)
            f.annotations.append(note(codes.LATE_RESPONSE, f"answers #{req.index} {lat / 1e6:.1f} ms after it; "
                                                           f"the master had moved on ({ended})", 0, len(f.raw)))
            return True
        return False

    def _request(self, f: Frame) -> list[Frame]:
        req = self.pending
        if req is not None:  # held is empty unless a request is pending
            out = self._unanswered("next request", f.t_ns - req.t_end_ns if f.time_source != "none" else None)
            if req.raw == f.raw:
                f.annotations.append(note(codes.RETRY, f"repeats frame #{req.index}", 0, len(f.raw)))
                if f.time_source != "none" and f.t_ns > req.t_end_ns:
                    self.waits.append(f.t_ns - req.t_end_ns)  # the master's timer: how long it waits
        else:
            out = []
        self.last_request = f
        if f.unit != 0 and f.crc_ok is not False:
            self.latest[(f.unit, f.function)] = f
        if f.unit == 0:
            f.annotations.append(note(codes.BROADCAST, "no response expected", 0, 1))
            if f.protocol in _MODBUS and f.function not in BROADCAST_FUNCTIONS:
                f.annotations.append(note(codes.BROADCAST_FUNCTION,
                                          f"function 0x{f.function:02X} to unit 0: no unit may answer it", 1, 2))
            out.append(f)
            return out
        self.pending = f
        self.held.append(f)
        return out

    def _unanswered(self, ended_by: str, waited_ns: int | None, code=codes.NO_RESPONSE) -> list[Frame]:
        """Settle the pending request without a response; the held frames, in capture order.

        One annotation says what ended the wait ("next request", "timeout
        tick", "end of capture") and after how long; pair.timeout follows
        when that wait is known to be past the unit's timeout.
        """
        req = self.pending
        after = "" if waited_ns is None else f" after {waited_ns / 1e6:.1f} ms"
        req.annotations.append(note(code, f"no response: {ended_by}{after}", 0, len(req.raw)))
        limit = self.timeout_for(req.unit)
        if waited_ns is not None and waited_ns > limit:
            req.annotations.append(
                note(codes.TIMEOUT, f"unit {req.unit}: no response within {limit / 1e6:.0f} ms", 0, len(req.raw))
            )
        self.pending = None
        if code is codes.NO_RESPONSE:
            self.recent.append((req, f"{ended_by}{after}"))
        out = self.held
        self.held = []
        return out

    def cut_state(self, offset: int) -> tuple:
        """What this pairer carries past a cut (sniffer.parallel), frame numbers counted from `offset` (the
        first number after the cut): the pending request and what it holds, and the last request only while
        it is the frame just before (a broadcast an answer may follow: `_answers_broadcast`)."""
        def ref(f):
            return (f.index - offset, f.t_ns, f.t_end_ns, f.raw, f.protocol, f.unit, f.function, f.crc_ok, f.role,
                    f.adu, f.time_source)

        last = self.last_request
        last = ref(last) if last is not None and last.index == self._last_index else None
        return (None if self.pending is None else ref(self.pending), tuple(ref(f) for f in self.held), last,
                self.timeout_ns, tuple(sorted(self.unit_timeouts.items())))

    def waiting(self) -> dict | None:
        """The request waiting for its answer, as a part cut now carries it (`resume`); None if none."""
        req = self.pending
        if req is None:
            return None
        return {"t_ns": req.t_ns, "t_end_ns": req.t_end_ns, "raw": req.raw.hex(), "protocol": req.protocol,
                "unit": req.unit, "function": req.function, "crc_ok": req.crc_ok, "time_source": req.time_source,
                "adu": bytes(req.adu).hex()}

    def resume(self, waiting: dict) -> None:
        """Start as the part before ended: its request waiting for an answer (`waiting`), so an answer at this
        part's start is that request's response, not a request of its own.  The request is the part before's:
        it is never handed on here (unanswered, it settles with nothing to show)."""
        try:
            raw = bytes.fromhex(waiting["raw"])
            req = Frame(-1, int(waiting["t_ns"]), int(waiting["t_end_ns"]), raw, str(waiting["protocol"]),
                        waiting.get("unit"), waiting.get("function"), crc_ok=waiting.get("crc_ok"),
                        time_source=str(waiting.get("time_source") or "byte"))
            adu = waiting.get("adu")
            req.adu = bytes.fromhex(adu) if isinstance(adu, str) else b""
        except (KeyError, TypeError, ValueError):
            return  # metadata of another version or damaged: start as a capture does
        req.role = REQUEST
        self.pending, self.held = req, []

    def would_time_out(self, t_ns: int) -> bool:
        """True if tick(t_ns) would settle the pending request (used to record effective ticks)."""
        req = self.pending
        return req is not None and t_ns - req.t_end_ns > self.timeout_for(req.unit)

    def tick(self, t_ns: int) -> list[Frame]:
        if not self.would_time_out(t_ns):
            return []
        return self._unanswered("timeout tick", t_ns - self.pending.t_end_ns)

    def flush(self) -> list[Frame]:
        if self.pending is not None:
            return self._unanswered("end of capture", None, codes.END_OF_CAPTURE)
        out = self.held
        self.held = []
        return out


def _answer_head(req: bytes, raw: bytes) -> bool:
    """Does a damaged frame start as an answer to `req` would (an exception; a read's byte count)?  A damaged
    repeat of the request itself (the master's retry, a stray byte glued on) does not."""
    if len(req) < 2 or len(raw) < 3:
        return False
    if raw[1] & 0x80:
        return True
    fc = req[1]
    if fc in (0x01, 0x02, 0x03, 0x04) and len(req) >= 6:
        qty = (req[4] << 8) | req[5]
        return raw[2] == (2 * qty if fc >= 3 else (qty + 7) // 8)
    return False


# the annotations whose text names other frames by number ("#N": `_ref`), renumbered with them
_NAMING_CODES = frozenset({codes.ROLE_AMBIGUOUS.code, codes.BROADCAST_RESPONSE.code, codes.ORPHAN_RESPONSE.code,
                           codes.RETRY.code})
_NUMBER = re.compile(r"#(\d+)")


def renumber(frames, delta: int) -> None:
    """Move frames decoded as a part of their own to their numbers in the whole capture (sniffer.parallel):
    index and pair by `delta`, and the frame numbers the pairer's notes name."""
    def shift(m):
        return f"#{int(m.group(1)) + delta}"

    for f in frames:
        f.index += delta
        if f.pair is not None:
            f.pair += delta
        anns = f.annotations
        for k, a in enumerate(anns):
            if a.code in _NAMING_CODES and "#" in a.detail:
                anns[k] = a._replace(detail=_NUMBER.sub(shift, a.detail))


def _same_transaction(req: Frame, f: Frame) -> bool:
    return req.unit == f.unit and (f.function == req.function or f.function == (req.function | 0x80))


def response_mismatch(req: bytes, rsp: bytes) -> str | None:
    """Why a CRC-good response does not answer its CRC-good request, or None (ADUs, no checksum)."""
    try:
        fc = req[1]
        if rsp[1] & 0x80:
            return None
        if fc in (0x01, 0x02):
            qty = (req[4] << 8) | req[5]
            want = (qty + 7) // 8
            if rsp[2] != want:
                return f"byte count {rsp[2]}, expected {want} for {qty} bits"
        elif fc in (0x03, 0x04):
            qty = (req[4] << 8) | req[5]
            if rsp[2] != 2 * qty:
                return f"byte count {rsp[2]}, expected {2 * qty} for {qty} registers"
        elif fc in (0x05, 0x06, 0x16):
            if rsp != req:
                return "response is not an echo of the request"
        elif fc == 0x08:
            if rsp[2:4] != req[2:4]:
                return "diagnostic sub-function not echoed"
        elif fc in (0x0F, 0x10):
            if rsp[2:6] != req[2:6]:
                ra, rq = (req[2] << 8) | req[3], (req[4] << 8) | req[5]
                sa, sq = (rsp[2] << 8) | rsp[3], (rsp[4] << 8) | rsp[5]
                return f"response says address {sa} x {sq}, request was {ra} x {rq}"
        elif fc == 0x17:
            qty = (req[4] << 8) | req[5]
            if rsp[2] != 2 * qty:
                return f"byte count {rsp[2]}, expected {2 * qty} for {qty} registers"
    except IndexError:
        if len(req) < 2 or len(rsp) < 2:
            return None  # no function code to compare (a framer never pairs such ADUs; built frames may)
        return "response too short for its request"
    return None


__all__ = ["Pairer", "response_mismatch", "UNKNOWN"]
