"""Modbus RTU framer: silence first, but not silence only.

Sans-I/O: `feed(chunk)`, `tick(t_ns)` and `flush()` return finished Frames.

What the framer knows about each byte boundary (linebuf.LineBuffer):
  HARD  silence >= t3.5 (per-byte times), a large gap between reads, a line
        (channel) change, a tick that proved silence, or a pcap packet's edges:
        frames never span it.
  SOFT  silence >= 1.5 characters (per-byte times), or the start of a new USB
        read: a likely boundary, but frames may span it (an adapter splits
        frames across reads; a sloppy master pauses mid-frame).
  none  bytes known back to back, or inside one read (unknown timing).

At each frame start the framer tries, in this order (`Crc16Framing._step`),
each rule a method named for it:
  A. `_rule_a_structural`: the lengths implied by unit, function code and
     byte count, shortest first, with a valid CRC: that is a frame (cuts
     glued frames, rejoins split ones, and a frame followed by 0x00 bytes is
     not swallowed).  `_fast` is the same rule in one tight loop for per-read
     bytes, the bulk of a USB capture;
  B1. `_rule_b1_crc_run`: the run of bytes up to the next boundary, if its
     CRC is valid (a frame whose length contradicts its function code, or an
     unknown code);
  B2. `_rule_b2_noise_before_frame`: if a CRC-valid structural frame starts
     later, before the boundary, and its end is plausible too (boundary, end
     of data, or another valid frame), the bytes before it are noise (noise
     glued to a frame in one read);
  B3. `_rule_b3_damaged_frame`: a structural length that ends exactly at the
     next boundary, bad CRC (a corrupted frame);
  B3b. `_rule_b3b_frame_inside`: a good frame wholly inside the run, junk on
     both sides of it;
  B3c. `_rule_b3c_crc_pieces`: the run splits wholly into CRC-valid pieces
     (glued frames no length rule cuts), a few junk bytes before them allowed;
  B4. `_rule_b4_malformed_burst`: a whole burst between two t3.5 silences
     with a plausible header is a malformed frame (the Modbus definition of
     a frame), bad CRC; shorter than a length its header announces, it is
     that frame cut off (its roles, `modbus.length.truncated`);
  B5. `_rule_b5_noise`: otherwise noise up to the next boundary.
B2 judges the bytes before the good frame as a run of their own: CRC-valid
-> a frame (B1's notes), a structural length ending there -> a damaged frame,
CRC-valid pieces -> frames, else noise.  Every unit gets the same lengths
(rtu_layout.candidates); the frame's bytes may narrow its roles
(rtu_layout.roles), and of two CRC-valid lengths the evidence decides, not the
length (`_prefer_longer`: UART flags, boundaries, what is pending).  A byte the
UART flagged is in no CRC-valid frame: a frame holding one is damaged
(`modbus.crc.unproven` when its CRC holds all the same).
Decisions depend only on bytes and boundaries, never on how reads were cut,
so feeding a capture whole, byte by byte or in random chunks gives the same
frames (a property test checks it).
"""

from __future__ import annotations

from sniffer import codes
from sniffer.codes import note
from sniffer.framing.crc import crc16_raw, crc_ok
from sniffer.framing.crc_rules import NEXT, Crc16Framing
from sniffer.frame import CAN_REQ, CAN_RSP, Frame
from sniffer.framing.linebuf import WAIT, HARD, MAX_NOISE, NONE, SOFT, LineBuffer
from sniffer.framing.rtu_lengths import KNOWN_FUNCTIONS, MAX_ADU, Need, candidates, roles
from sniffer.hot import HOT

__all__ = ["RtuFramer", "HARD", "SOFT", "NONE", "MAX_NOISE", "WAIT"]
_READS = frozenset((0x01, 0x02, 0x03, 0x04))  # request 8 bytes, response byte count + 5
_ECHOES = frozenset((0x05, 0x06, 0x08))  # 8 bytes both ways


class RtuFramer(Crc16Framing, LineBuffer):
    protocol = "modbus-rtu"
    codes = codes.RTU_CODES
    # `_fast`'s loop compiled (sniffer/_hot.c rtu_fast: same decisions, it hands every case it does not
    # settle back to `_step`); None: `_fast` itself runs (SNIFFER_PURE, no compiler, or a subclass that says so)
    _compiled_fast = None if HOT is None else staticmethod(HOT.rtu_fast)

    def noise_reason(self, raw: bytes) -> str:
        return _noise_reason(raw)

    def _run(self) -> list[Frame]:
        self._need = 0
        out: list[Frame] = []
        # rule A for per-read bytes first; a flagged byte needs the rule-by-rule path. When
        # _fast stops where _step would wait too (the rest of a frame), _step is not asked
        waits = False
        if not self.flags:
            fast = self._compiled_fast
            waits = self._fast(out) if fast is None else fast(self, out, Frame, roles)
            if out:
                self._last_good = (out[-1].role_fits, out[-1].raw)
        if not waits:
            step = self._step
            while (fr := step(self.pos)) is not None:
                out.append(fr)
        self._compact()
        return out

    def _fast(self, out: list[Frame]) -> bool:
        """Rule A for per-read bytes in one tight loop: the bulk of a USB capture.

        Same decisions as `_step` (shortest CRC-valid structural length first,
        never across a HARD boundary); it stops at the first byte it cannot
        settle alone (per-byte times, a flag, an unusual function code, a bad
        CRC, bytes still to come) and `_step` carries on from there.  True when
        it stopped where `_step` would wait too: a candidate runs past the
        bytes so far and more can come (`_need` set as `_crc_candidate` sets it).
        """
        buf, base = self.buf, self.base
        p = self.pos
        limit, final = self._avail(p)
        lim = limit - base
        segs = self.segs
        k = 0
        nseg = len(segs)
        while k < nseg and p >= segs[k][0] + len(segs[k][1].data):
            k += 1
        if k >= nseg:
            return False
        s0, c0 = segs[k]
        if c0.byte_t_ns is not None:
            return False
        char = self.char_ns
        index = self.index
        prev_end = self.prev_frame_end_ns
        modbus = crc16_raw
        p0 = p
        data = bytes(buf[p - base : lim])  # one copy per call: slices of bytes are bytes
        lim -= p - base
        end0 = s0 + len(c0.data)  # absolute end of the current read
        while True:
            i = p - p0
            if i + 5 > lim:
                break
            cands = _quick(data, i, lim)
            if cands is None:
                break
            length = 0
            for n, can in cands:  # noqa: B007 - `can` (the roles of the length found) is used after the break
                if i + n > lim:
                    if not final:
                        self.index, self.prev_frame_end_ns, self.pos = index, prev_end, p
                        self._need = p + n
                        return True
                    break
                raw = data[i : i + n]
                if not modbus(raw):
                    length = n
                    break
            if not length:
                break
            e = p + length
            if cands[-1][0] != length:  # a longer length of this header may hold a CRC too: _prefer_longer
                at = self._is_boundary(e, limit, final)
                if not at:
                    for n2, _can2 in cands:
                        if n2 <= length:
                            continue
                        if at is None or i + n2 > lim:
                            if final and at is not None:
                                continue
                            self.index, self.prev_frame_end_ns, self.pos = index, prev_end, p
                            self._need = e + 1 if at is None else p + n2
                            return True  # what follows decides: wait for it
                        raw2 = data[i : i + n2]
                        if not modbus(raw2):
                            at2 = self._is_boundary(p + n2, limit, final)
                            if at2 is None:
                                self.index, self.prev_frame_end_ns, self.pos = index, prev_end, p
                                self._need = p + n2 + 1
                                return True
                            if at2:  # the longer ends at a boundary: what is pending decides (_prefer_longer)
                                self.index, self.prev_frame_end_ns, self.pos = index, prev_end, p
                                return False
            t0 = c0.t_ns - (end0 - p) * char
            while e > end0:  # the frame ends in a later read
                k += 1
                s0, c0 = segs[k]
                end0 = s0 + len(c0.data)
                if c0.byte_t_ns is not None:
                    self.index, self.prev_frame_end_ns, self.pos = index, prev_end, p
                    return False
            t1 = c0.t_ns - (end0 - e) * char
            if can == 3 and raw[1] < 5:  # 01-04 in 8 bytes with byte count 3: the bytes may decide the role
                can = roles(raw[:-2], can)[0]
            fr = Frame(index, t0, t1, raw, "modbus-rtu", raw[0], raw[1], can, True, None, self.time_source or "read",
                       None if prev_end is None else t0 - prev_end, None, c0.channel)
            fr.adu = raw[:-2]
            out.append(fr)
            index += 1
            prev_end = t1
            p = e
            if e >= end0:
                k += 1
                if k >= nseg:
                    break
                s0, c0 = segs[k]
                end0 = s0 + len(c0.data)
                if c0.byte_t_ns is not None:
                    break
        self.index, self.prev_frame_end_ns, self.pos = index, prev_end, p
        return False

    def _crc_candidate(self, p: int, end: int, final: bool):
        """First (shortest) structural candidate at p with a good CRC: (len, can, raw), False, or WAIT."""
        buf, base = self.buf, self.base
        i = p - base
        n = end - base
        if i + 2 < n:  # fast path for the function codes that make up nearly all traffic
            quick = _quick(buf, i, n)
            if quick is not None:
                for k, (length, can) in enumerate(quick):
                    if i + length > n:
                        if final:
                            return False
                        self._need = p + length
                        return WAIT
                    raw = bytes(buf[i : i + length])
                    if not crc16_raw(raw) and not (self.flags and self._flagged(p, p + length)):
                        if k + 1 < len(quick):
                            return self._prefer_longer(p, (length, can, raw), quick[k + 1 :], end, final)
                        return length, can, raw
                return False
        cands = candidates(buf, i, n)
        for k, (length, can) in enumerate(cands):
            if type(length) is Need:
                if final:
                    continue
                return WAIT
            if p + length > end:
                if final:
                    continue
                return WAIT
            raw = bytes(buf[i : i + length])
            if crc_ok(raw) and not self._flagged(p, p + length):
                if k + 1 < len(cands):
                    return self._prefer_longer(p, (length, can, raw), cands[k + 1 :], end, final)
                return length, can, raw
        return False

    def _prefer_longer(self, p: int, hit: tuple, longer, end: int, final: bool):
        """Two lengths of one header both carry a valid CRC: the shorter is taken unless the evidence
        says otherwise, never the length alone.  CRC-16 makes this common: any frame followed by a
        0x00 checks one byte longer too (a request's 8 bytes and the 0x00 a line driver leaves at
        turn-off read as a 9-byte response when the request's third byte is 04), and a 9-byte read
        response's first 8 bytes pass as a request about 1 in 65536 times.  The evidence, in order:
        a flagged byte is in no CRC-valid reading (`_crc_candidate` skips it); the shorter ends at a
        boundary: the shorter; the longer ends at a boundary and what is pending allows it
        (`_roles_allow_longer`): the longer.  Only bytes, flags, boundaries and the frames before
        decide, so a frame waits while the longer one's bytes are coming."""
        at = self._is_boundary(p + hit[0], end, final)
        if at is None:
            return WAIT  # the shorter ends where the bytes so far end: what follows decides
        if at:
            return hit  # the shorter ends at a boundary
        buf, i = self.buf, p - self.base
        for length, can in longer:
            if type(length) is Need or p + length > end:
                if final:
                    continue
                if type(length) is not Need:
                    self._need = p + length
                return WAIT
            raw = bytes(buf[i : i + length])
            if crc_ok(raw) and not self._flagged(p, p + length):
                at = self._is_boundary(p + length, end, final)
                if at is None:
                    return WAIT
                if at and self._roles_allow_longer(hit, (length, can, raw)):
                    return length, can, raw
        return hit

    def _roles_allow_longer(self, short: tuple, long: tuple) -> bool:
        """What is pending, and the roles each reading can have, allow the longer of two CRC-valid
        readings (length, roles, raw) of one header?  A reading that can only be a response needs
        the pending request it answers (unit, function, size or echo); a shorter reading that
        answers it, or repeats it byte for byte (a retry), wins.  Before the first frame, and after
        a damaged one, nothing is pending."""
        last = self._last_good
        req = last[1] if last is not None and last[0] & CAN_REQ else None
        if req is not None:
            if short[2] == req:
                return False
            s_ans = bool(short[1] & CAN_RSP) and _answers(req, short[2])
            l_ans = bool(long[1] & CAN_RSP) and _answers(req, long[2])
            if s_ans and not l_ans:
                return False
            if l_ans:
                return True
        return bool(long[1] & CAN_REQ)

    # --------------------------------------------------------------- rules
    def _rule_a_structural(self, p: int, end: int, final: bool):
        """A: a structural length (unit, function, byte count) with a good CRC, shortest first."""
        hit = self._crc_candidate(p, end, final)
        if hit is WAIT:
            return WAIT
        if hit:
            return self._emit(p, p + hit[0], hit[1], crc_good=True, raw=hit[2])
        return NEXT

    def _rule_b1_crc_run(self, p: int, b: int, end: int, final: bool):
        """B1: the run up to the boundary carries a valid CRC: a frame of the wrong length or an
        unknown / user-defined function (annotated so)."""
        seg = bytes(self.buf[p - self.base : b - self.base])
        if not (len(seg) >= 4 and crc_ok(seg)) or self._flagged(p, b):
            return NEXT
        return self._crc_run(p, b, seg)

    def _crc_run(self, p: int, b: int, seg: bytes) -> Frame:
        """[p, b) holds a valid CRC but no length the header explains: a frame all the same,
        annotated (wrong length for a known function, or an unknown / user-defined one)."""
        fc = seg[1]
        fr = self._emit(p, b, CAN_REQ | CAN_RSP, crc_good=True, raw=seg)
        base_fc = fc & 0x7F
        if base_fc in KNOWN_FUNCTIONS and fc != 0x80:
            fr.annotations.append(
                note(codes.LENGTH_MISMATCH, f"{len(seg)} bytes do not fit function 0x{fc:02X}", 0, len(seg))
            )
        else:
            user = 65 <= base_fc <= 72 or 100 <= base_fc <= 110
            fr.annotations.append(
                note(codes.FUNCTION_USER if user else codes.FUNCTION_UNKNOWN,
                     f"function 0x{fc:02X} ({fc}) shown raw", 1, 2)
            )
        return fr

    def _rule_b2_noise_before_frame(self, p: int, b: int, end: int, final: bool):
        """B2: a good frame starts at q in (p, b) and ends plausibly.  The start of a good frame is a
        clear boundary, so [p, q) is judged as a run of its own first: a valid CRC makes it a frame
        (a diagnostic 08 without data glued to the next frame), a header whose length ends exactly
        at q a damaged frame (a bad-CRC exception glued to the good retry); else it is noise."""
        q = self._resync(p, b, end, final)
        if q is WAIT:
            return WAIT
        if q >= b:
            return NEXT
        return self._lead_run(p, q)

    def _lead_run(self, p: int, q: int) -> Frame:
        """[p, q) before a good frame: a CRC-valid run, a damaged structural frame, or noise."""
        buf, base = self.buf, self.base
        seg = bytes(buf[p - base : q - base])
        flagged = self._flag_offsets(p, q)
        if len(seg) >= 4 and crc_ok(seg) and not flagged:  # any function: an unknown or user-defined one is annotated
            return self._crc_run(p, q, seg)
        if len(seg) >= 4 and (seg[1] & 0x7F) in KNOWN_FUNCTIONS and seg[1] != 0x80:
            for length, can in candidates(buf, p - base, q - base):
                if length == q - p and type(length) is int:
                    return self._emit(p, q, can, crc_good=False, raw=seg)
        cut = _crc_partition(seg, flagged=flagged)
        if cut:
            return self._crc_run(p, p + cut, seg[:cut])
        return self._emit_noise(p, q)

    def _rule_b3b_frame_inside(self, p: int, b: int, end: int, final: bool):
        """B3b: a good frame lies wholly inside [p, b) with junk on both sides of it (one read holding
        noise, a frame and noise): the bytes before it go first (as B2 judges them); its end need not
        be plausible, as nothing else explains the run.  Tried after B3 so a damaged frame's data
        is not searched for a chance CRC match."""
        hit = self._crc_candidate
        for q in range(p + 1, b - 3):
            if (buf_q1 := self.buf[q + 1 - self.base]) & 0x7F not in KNOWN_FUNCTIONS or buf_q1 == 0x80:
                continue
            if hit(q, b, True):
                return self._lead_run(p, q)
        return self._rule_b3c_crc_pieces(p, b)

    def _rule_b3c_crc_pieces(self, p: int, b: int):
        """B3c: the run splits wholly into CRC-valid pieces (frames of an unknown or user-defined
        function, or 08s without data, glued in one read, which no length rule cuts): the first
        is a frame (B1's notes)."""
        if b - p > 4 * MAX_ADU:
            return NEXT
        seg = bytes(self.buf[p - self.base : b - self.base])
        flagged = self._flag_offsets(p, b)
        cut = _crc_partition(seg, flagged=flagged)
        if cut:
            return self._crc_run(p, p + cut, seg[:cut])
        for q in range(1, min(JUNK_BEFORE, len(seg) - 4) + 1):  # a few bytes of line noise before them
            if _crc_partition(seg[q:], whole_ok=True, flagged=frozenset(k - q for k in flagged if k >= q)):
                return self._emit_noise(p, p + q)
        return NEXT

    def _rule_b3_damaged_frame(self, p: int, b: int, end: int, final: bool):
        """B3: a structural length ending exactly at the boundary, bad CRC; with per-read times
        also one that runs over read boundaries to a later boundary (`_damaged_ends_at`)."""
        buf, base = self.buf, self.base
        per_read = not self._per_byte_at(p)
        for length, can in candidates(buf, p - base, (end if per_read else b) - base):
            if type(length) is not int:
                if per_read and not final:
                    return WAIT  # its length is not known yet
                continue
            e = p + length
            if e == b:
                return self._emit(p, b, can, crc_good=False)
            if per_read:
                at = self._damaged_ends_at(e, b, end, final)
                if at is WAIT:
                    return WAIT
                if at:
                    return self._emit(p, e, can, crc_good=False)
        return NEXT

    def _rule_b4_malformed_burst(self, p: int, b: int, end: int, final: bool):
        """B4: a whole burst between two t3.5 silences is a frame by the Modbus definition: with a
        plausible header (unit, known function) it is a malformed frame (bad CRC, wrong length)."""
        buf, base = self.buf, self.base
        if not (b - p >= 4 and buf[p - base] <= 247 and (buf[p + 1 - base] & 0x7F) in KNOWN_FUNCTIONS
                and self._whole_burst(p, b, end, final)):
            return NEXT
        n = b - p
        cut = [(length, can) for length, can in candidates(buf, p - base, b - base)
               if type(length) is int and length > n]
        if cut:  # the frame its header announces, cut off (a logger's packet limit, a dropped line)
            want = cut[0][0]
            fr = self._emit(p, b, sum_roles(can for length, can in cut if length == want), crc_good=False)
            fr.annotations.append(note(codes.LENGTH_TRUNCATED, f"cut off: {n} of the {want} bytes its header "
                                                               f"announces ({want - n} missing)", 0, n))
            return fr
        fr = self._emit(p, b, CAN_REQ | CAN_RSP, crc_good=False)
        fr.annotations.append(
            note(codes.LENGTH_MISMATCH, f"{n} bytes do not fit function 0x{buf[p + 1 - base]:02X}", 0, n)
        )
        return fr

    def _frame_starts_at(self, q: int, b: int, end: int, final: bool):
        """B2's test at q: a plausible header, a structural frame with a good CRC, and a plausible
        end (a boundary, or another such frame right after it)."""
        buf, base = self.buf, self.base
        if q + 1 >= end:
            return False if final else WAIT
        fc = buf[q + 1 - base]
        if (fc & 0x7F) not in KNOWN_FUNCTIONS or fc == 0x80:
            return False
        hit = self._crc_candidate(q, end, final)
        if hit is WAIT:
            return WAIT
        if not hit:
            return False
        e = q + hit[0]
        at = self._is_boundary(e, end, final)
        if at is None:
            return WAIT
        if at:
            return True
        nxt = self._crc_candidate(e, end, final)
        if nxt is WAIT:
            return WAIT
        return bool(nxt)

    # -------------------------------------------------------------- output
    def _header(self, fr: Frame, adu: bytes, crc_good: bool) -> None:
        fr.unit = adu[0]
        fr.function = adu[1]
        fr.adu = adu
        if adu[0] > 247:
            fr.annotations.append(note(codes.UNIT_RESERVED, f"unit {adu[0]} (248-255 are reserved)", 0, 1))
        fr.role_fits, why = roles(adu, fr.role_fits)
        if why:
            fr.annotations.append(note(codes.STRUCTURE_MISMATCH, why, 2, len(adu)))

    def _short_silence_note(self, idle_ns: int):
        return note(codes.T35_SHORT, f"{idle_ns / self.char_ns:.2f} characters of silence before the frame", 0, 1)


def _read_cands(lr: int) -> tuple:
    if lr < 8:
        return ((lr, CAN_RSP), (8, CAN_REQ))
    if lr == 8:
        return ((8, CAN_REQ | CAN_RSP),)
    return ((8, CAN_REQ), (lr, CAN_RSP))


# candidate tuples built once: a read's by its response byte count, a write-multiple's by
# its request byte count (buf[i + 6]); _quick runs for every frame
_READ_CANDS = tuple(_read_cands(bc + 5) for bc in range(256))
_WRITE_CANDS = tuple(((8, CAN_RSP), (bc + 9, CAN_REQ)) for bc in range(256))
_ECHO_CANDS = ((8, CAN_REQ | CAN_RSP),)
_WRITE_WAIT = ((8, CAN_RSP),)
_EXC_CANDS = ((5, CAN_RSP),)


def _quick(buf, i: int, n: int):
    """Candidates (length, roles), shortest first, for the function codes of nearly all traffic.

    None when unit/function are not one of those cases (the full rules in
    rtu_layout apply).  Needs buf[i + 2] to exist (i + 2 < n).
    """
    if not 0 < buf[i] <= 247:
        return None
    fc = buf[i + 1]
    if fc in _READS:  # request 8 bytes, response byte count + 5
        return _READ_CANDS[buf[i + 2]]
    if fc in _ECHOES:
        return _ECHO_CANDS
    if fc == 0x10 or fc == 0x0F:  # response 8 bytes, request byte count + 9
        if i + 8 > n:
            return _WRITE_WAIT  # the request is longer still: wait for the response length first
        return _WRITE_CANDS[buf[i + 6]]
    if fc & 0x80 and fc != 0x80:
        return _EXC_CANDS
    return None


JUNK_BEFORE = 8  # bytes of noise B3c looks past for glued CRC-valid runs (each try costs up to 256 CRCs)


def _crc_partition(seg: bytes, whole_ok: bool = False, flagged: frozenset[int] = frozenset()) -> int:
    """The length of the first piece when `seg` splits wholly into CRC-valid runs of 4..256 bytes,
    shortest pieces first; 0 if it does not (or is one piece, unless `whole_ok`).  A chance CRC
    match splits no run: every piece must hold one, end to end.  A piece holding a flagged byte
    (an offset in `flagged`) is not CRC-valid."""
    n = len(seg)

    def good(i: int, j: int) -> bool:
        return crc_ok(seg[i:j]) and not any(i <= k < j for k in flagged)

    if whole_ok and 4 <= n <= MAX_ADU and good(0, n):
        return n
    memo: dict[int, bool] = {n: True}

    def whole(i: int) -> bool:  # seg[i:] splits into CRC-valid runs
        hit = memo.get(i)
        if hit is None:
            hit = memo[i] = any(good(i, j) and whole(j) for j in range(i + 4, min(n, i + MAX_ADU) + 1))
        return hit

    for j in range(4, min(n - 4, MAX_ADU) + 1):
        if good(0, j) and whole(j):
            return j
    return 0


def sum_roles(cans) -> int:
    out = 0
    for can in cans:
        out |= can
    return out


def _answers(req: bytes, raw: bytes) -> bool:
    """Does `raw`, read as a response, answer the request `req` (both with their CRC): same unit
    (never a broadcast's) and function, and the size or echo the request asks for?"""
    if req[0] == 0 or raw[0] != req[0] or (raw[1] & 0x7F) != req[1]:
        return False
    fc = raw[1]
    if fc & 0x80:
        return True
    if fc <= 0x04 and len(req) == 8:
        qty = (req[4] << 8) | req[5]
        return raw[2] == (2 * qty if fc >= 0x03 else (qty + 7) // 8) and len(raw) == raw[2] + 5
    if fc in (0x0F, 0x10):
        return len(raw) == 8 and raw[2:6] == req[2:6]
    if fc in (0x05, 0x06):
        return raw == req
    return True


def _noise_reason(raw: bytes) -> str:  # RtuFramer.noise_reason
    if len(raw) < 4:
        return f"{len(raw)} byte(s): too short for a frame"
    if raw[0] > 247:
        return f"no frame: unit {raw[0]} is reserved and no valid CRC"
    fc = raw[1]
    if (fc & 0x7F) not in KNOWN_FUNCTIONS or fc == 0x80:
        return f"no frame: unknown function 0x{fc:02X} and no valid CRC"
    return f"no frame: function 0x{fc:02X} but length/CRC do not fit"
