"""The line as the framers see it: bytes, their times, and the silences between them.

Sans-I/O.  `feed(chunk)`, `tick(t_ns)` and `flush()` take input and return
the frames decided; a subclass decides one frame at a time in `_step(p)`
(RtuFramer, AsciiFramer, the PD framers; `Crc16Framing` and `HexLineFraming`
hold what the binary and the ':' ... CR LF framings share).

What the buffer knows about each byte boundary:
  HARD  silence >= t3.5 (per-byte times), a large gap between reads, a line
        (channel) change, a tick that proved silence, or the edges of a capturing
        tool's packet (`Chunk.packet`: pcap): frames never span it.
  SOFT  silence >= 1.5 characters (per-byte times), or the start of a new USB
        read: a likely boundary, but frames may span it.
  none  bytes known back to back, or inside one read (unknown timing).
Per-read bytes get times estimated back from the read's time (the last byte
arrived just before the read returned, characters back to back).

A byte the UART flagged (framing or parity error) is kept and annotated, but
it is no evidence for a check: a CRC or LRC that holds over it proves
nothing (`_flagged`), so it never ends up inside a CRC-valid frame.  (CRC-16
alone cannot tell a frame from the same frame plus a 0x00: a line driver's
turn-off glitch, received as 0x00 with a framing error, must not extend the
frame before it.)
"""

from __future__ import annotations

from collections import deque

from sniffer import codes
from sniffer.codes import note
from sniffer.events import FLAG_FRAMING, Chunk
from sniffer.frame import Frame
from sniffer.line import LineSettings
from sniffer.framing.rtu_lengths import MAX_ADU

NONE, SOFT, HARD = 0, 1, 2
MAX_NOISE = MAX_ADU  # a noise frame never holds more than this many bytes
WAIT = None


class LineBuffer:
    protocol = "line"
    codes = codes.LINE_CODES
    # None: each frame's time source is its chunk's ("byte" or "read"); "none": the input has no
    # time (frames typed in, `sniffer decode`): no timing verdicts (Pipeline sets it from CaptureInfo)
    time_source: str | None = None

    def __init__(self, line: LineSettings, *, read_slack_ns: int = 50_000_000) -> None:
        self.line = line
        self.char_ns = line.char_ns
        self.soft_ns = line.char_ns * 3 // 2
        self.hard_ns = line.t35_ns
        self.t15_ns = line.t15_ns
        # a per-read gap is silence only beyond t3.5 plus the adapter's latency slack:
        # a 16 ms latency timer plus a host that wakes 15-30 ms late must not cut a frame
        self.read_slack_ns = read_slack_ns
        self.buf = bytearray()
        self.base = 0  # absolute index of buf[0]
        self.pos = 0  # absolute index of the next undecided byte
        self.segs: deque = deque()  # (abs_start, Chunk)
        self.bounds: deque = deque()  # (abs_pos, SOFT|HARD), ascending
        self.flags: deque = deque()  # (abs_pos, flag), ascending
        self.closed = False  # silence proven after the last byte (tick/flush)
        self.last_t_end: int | None = None  # end of the last byte seen (ns)
        self.last_channel: str | None = None
        self.index = 0
        self.prev_frame_end_ns: int | None = None
        self._need = 0  # absolute end of the bytes the pending decision waits for

    # ---------------------------------------------------------------- input

    def feed(self, chunk: Chunk) -> list[Frame]:
        data = chunk.data
        if not data:
            return []
        start = self.base + len(self.buf)
        n = len(data)
        char = self.char_ns
        bt = chunk.byte_t_ns
        if bt is not None:
            first_t = bt[0]
            end_t = bt[-1] + char
        else:
            first_t = chunk.t_ns - n * char
            end_t = chunk.t_ns
            if chunk.unseen_ns is not None:  # the bytes may have come as early as the reader's last empty look
                first_t = min(first_t, chunk.t_ns - chunk.unseen_ns)
        cls = self._class_before(chunk, first_t)
        if cls:
            self.bounds.append((start, cls))
        if bt is not None and n > 1:
            soft, hard = self.soft_ns + char, self.hard_ns + char
            prev = bt[0]
            bounds = self.bounds
            for i in range(1, n):
                t = bt[i]
                d = t - prev
                if d >= soft:
                    bounds.append((start + i, HARD if d >= hard else SOFT))
                prev = t
        for off, flag in chunk.flags:
            self.flags.append((start + off, flag))
        self.closed = chunk.packet  # a tool's packet ends where it drew the edge
        self.last_t_end = end_t
        self.last_channel = chunk.channel
        self.buf += data
        self.segs.append((start, chunk))
        if start + n < self._need and cls != HARD:
            return []  # the frame being waited for is still incomplete: nothing can change
        return self._run()

    def _class_before(self, chunk: Chunk, first_t: int) -> int:
        """The boundary before a chunk whose first byte began at first_t: HARD, SOFT or NONE."""
        if self.last_t_end is None or chunk.packet:
            return HARD
        if self.closed or (self.last_channel is not None and chunk.channel != self.last_channel):
            return HARD
        gap = first_t - self.last_t_end
        if chunk.byte_t_ns is None:
            return HARD if gap > self.hard_ns + self.read_slack_ns else SOFT
        return HARD if gap >= self.hard_ns else SOFT if gap >= self.soft_ns else NONE

    def closes_before(self, chunk: Chunk) -> bool:
        """Would feed(chunk) close every pending byte as it would at the end of the input (a silence, or a
        new wire, before the chunk's first byte)?  Then `close_now()` gives those frames, and feed(chunk)
        after it gives the chunk's own: what feed(chunk) alone gives, in the same order (sniffer.parallel
        cuts a capture there)."""
        if not chunk.data:
            return False
        bt = chunk.byte_t_ns
        if bt is not None:
            first_t = bt[0]
        else:
            first_t = chunk.t_ns - len(chunk.data) * self.char_ns
            if chunk.unseen_ns is not None:
                first_t = min(first_t, chunk.t_ns - chunk.unseen_ns)
        return self._class_before(chunk, first_t) == HARD

    def close_now(self) -> list[Frame]:
        """Close every pending byte, as a silence proven after the last one does (`closes_before`)."""
        self.closed = True
        return self._run()

    def tick(self, t_ns: int) -> list[Frame]:
        """Silence until t_ns: once it exceeds t3.5 (+ read slack), close what is pending."""
        if not self.would_close(t_ns):
            return []
        self.closed = True
        return self._run()

    def would_close(self, t_ns: int) -> bool:
        """True if tick(t_ns) would close pending bytes (used to record effective ticks)."""
        if self.closed or self.last_t_end is None or self.pos >= self.base + len(self.buf):
            return False
        limit = self.hard_ns + (self.read_slack_ns if self._per_read_tail() else 0)
        return t_ns - self.last_t_end > limit

    def flush(self) -> list[Frame]:
        """End of input: everything pending becomes frames."""
        self.closed = True
        return self._run()

    def pending_bytes(self) -> int:
        return self.base + len(self.buf) - self.pos

    def cut_state(self) -> tuple:
        """What this framer carries past a cut where no byte is pending (sniffer.parallel): every field, byte
        positions counted from `pos`, the frame counter left out (each part numbers its own).  Two framers
        with equal cut states frame what follows alike; a field a framing adds is compared as it is."""
        pos = self.pos
        out = []
        for k, v in sorted(vars(self).items()):
            if k in ("index", "base", "pos", "buf"):
                continue
            if k == "segs":
                v = tuple((start - pos, c) for start, c in v)
            elif k in ("bounds", "flags"):
                v = tuple((at - pos, what) for at, what in v)
            elif k == "_need":
                v = max(0, v - pos)
            out.append((k, v))
        out.append(("pending", bytes(self.buf[pos - self.base:])))
        return tuple(out)

    def pending_since(self) -> int | None:
        """When the first byte no frame holds yet began (the next frame starts there), or None."""
        return self._time_of(self.pos) if self.pos < self.base + len(self.buf) else None

    # ------------------------------------------------------------- decisions

    def _per_read_tail(self) -> bool:
        return bool(self.segs) and self.segs[-1][1].byte_t_ns is None

    def _avail(self, p: int) -> tuple[int, bool]:
        """(limit, final): bytes usable from p, and whether more can ever come before limit."""
        for b, c in self.bounds:
            if b > p and c == HARD:
                return b, True
        return self.base + len(self.buf), self.closed

    def _next_boundary(self, p: int, end: int, final: bool):
        for b, _c in self.bounds:
            if b > p:
                if b <= end:
                    return b
                break
        if final:
            return end
        if end - p >= MAX_NOISE:
            return p + MAX_NOISE  # no silence for a whole ADU: cut, deterministically
        return WAIT

    def _is_boundary(self, e: int, end: int, final: bool):
        """Is there a boundary (SOFT/HARD/end of data) at e? None while unknown."""
        if e >= end:
            return True if final else None
        for b, _c in self.bounds:
            if b == e:
                return True
            if b > e:
                break
        return False

    def _class_at(self, p: int) -> int:
        for b, c in self.bounds:
            if b == p:
                return c
            if b > p:
                break
        return NONE

    def _is_hard(self, e: int, end: int, final: bool) -> bool:
        if e >= end:
            return final
        return self._class_at(e) == HARD

    def _seg(self, i: int):
        for start, ch in self.segs:
            if i < start + len(ch.data):
                return start, ch
        raise IndexError(i)

    def _time_of(self, i: int) -> int:
        """Start time of absolute byte i (per read: estimated back from the read time)."""
        start, ch = self._seg(i)
        if ch.byte_t_ns is not None:
            return ch.byte_t_ns[i - start]
        return ch.t_ns - (start + len(ch.data) - i) * self.char_ns

    def _flagged(self, p: int, e: int) -> bool:
        """True if a byte in [p, e) came with a UART error (framing or parity): no check over it is proof."""
        for pos, _flag in self.flags:
            if pos >= e:
                return False
            if pos >= p:
                return True
        return False

    def _flag_offsets(self, p: int, e: int) -> frozenset[int]:
        """Offsets from p of the flagged bytes in [p, e)."""
        return frozenset(pos - p for pos, _flag in self.flags if p <= pos < e)

    def _unproven_note(self, p: int, e: int, check: str, start: int, end: int):
        """The annotation for a frame [p, e) whose check holds over flagged bytes (span: the check)."""
        offs = sorted(self._flag_offsets(p, e))
        which = ", ".join(str(k) for k in offs[:4]) + (", ..." if len(offs) > 4 else "")
        return note(codes.CRC_UNPROVEN, f"{check} matches, but byte {which} came with a UART error: "
                                        "no proof, taken as damaged", start, end)

    def _per_byte_at(self, i: int) -> bool:
        return self._seg(i)[1].byte_t_ns is not None

    def _new_frame(self, p: int, e: int, protocol: str, raw: bytes) -> Frame:
        char = self.char_ns
        s0, c0 = self._seg(p)
        n0 = len(c0.data)
        bt = c0.byte_t_ns
        per_byte = bt is not None
        t0 = bt[p - s0] if per_byte else c0.t_ns - (s0 + n0 - p) * char
        last = e - 1
        if last < s0 + n0:
            t1 = (bt[last - s0] if per_byte else c0.t_ns - (s0 + n0 - last) * char) + char
        else:
            t1 = self._time_of(last) + char
        idle = None if self.prev_frame_end_ns is None else t0 - self.prev_frame_end_ns
        fr = Frame(
            self.index, t0, t1, raw, protocol,
            time_source=self.time_source or ("byte" if per_byte else "read"),
            idle_before_ns=idle, channel=c0.channel,
        )
        self.index += 1
        self.prev_frame_end_ns = t1
        if self.flags:
            for pos, flag in self.flags:
                if pos >= e:
                    break
                if pos >= p:
                    c = codes.UART_FRAMING if flag == FLAG_FRAMING else codes.UART_PARITY
                    fr.annotations.append(note(c, f"byte {pos - p} flagged {flag}", pos - p, pos - p + 1))
        if per_byte and self.time_source is None:
            for bpos, _c in self.bounds:
                if bpos >= e:
                    break
                if bpos > p:
                    gap = self._time_of(bpos) - self._time_of(bpos - 1) - char
                    if gap > self.t15_ns:
                        fr.annotations.append(
                            note(codes.T15_VIOLATION, f"{gap / 1e6:.2f} ms silence before byte {bpos - p}",
                                 bpos - p, bpos - p + 1)
                        )
        return fr

    def _emit_noise(self, p: int, q: int) -> Frame:
        raw = bytes(self.buf[p - self.base : q - self.base])
        fr = self._new_frame(p, q, "noise", raw)
        reason = self.noise_reason(raw)
        fr.noise_reason = reason
        fr.annotations.append(note(codes.NOISE, reason, 0, len(raw)))
        self.pos = q
        return fr

    def _compact(self) -> None:
        pos = self.pos
        segs = self.segs
        while segs and segs[0][0] + len(segs[0][1].data) <= pos:
            segs.popleft()
        while self.bounds and self.bounds[0][0] < pos:  # keep the one at pos: _class_at(pos)
            self.bounds.popleft()
        while self.flags and self.flags[0][0] < pos:
            self.flags.popleft()
        drop = pos - self.base
        if drop > 4096 or (drop and drop == len(self.buf)):
            del self.buf[:drop]
            self.base = pos

    def noise_reason(self, raw: bytes) -> str:
        """Why these bytes form no frame, in the framing's own words (the framers override it)."""
        return f"{len(raw)} byte(s) that form no frame"

    # ------------------------------------------------------------ deciding
    def _run(self) -> list[Frame]:
        """Decide what the bytes so far allow: the frames, in order."""
        self._need = 0
        out: list[Frame] = []
        step = self._step
        while (fr := step(self.pos)) is not None:
            out.append(fr)
        self._compact()
        return out

    def _step(self, p: int) -> Frame | None:  # pragma: no cover - each framing decides its frames
        """The frame that starts at p (and moves `pos` past it), or None while it waits for bytes."""
        raise NotImplementedError
