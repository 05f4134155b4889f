"""A skeleton register map from traffic (`sniffer learn`): what was polled and written, and a type guess.

    learner = Learner()
    for frame in session:          # decoded frames (sans-I/O: frames in, a map out)
        learner.frame(frame)
    text = learner.to_toml("line3", "line3.mcap")   # a registers.toml: names for the engineer to fill in

What it keeps (bounded: a capture of any length fits):
- per unit: requests, responses, exceptions;
- per request block (unit, function, start, quantity): how often and over which time;
- per register (unit, table, address): every value's min / max, how often it rose or fell, up
  to `MAX_DISTINCT` distinct values, and the first `MAX_SAMPLES` values with the response they came
  in (two words are compared only as read together).

The guesses, each with the evidence in the row's note (`guess_pair`, `guess_word`):
- float32: two adjacent registers whose 32-bit float is finite and plausible in every sample
  while, as u16, the low word jumps (a mantissa's low bits) and the high word hardly moves
  (sign, exponent, top of the mantissa); high word first, else low word first (word_order);
- u32 counter: two words whose 32-bit value never falls while the low word wraps;
- constant, counter (never falls), s16 (values around zero, or all just under 0x10000), u16.
A guess is a starting point: the engineer confirms it against the device's manual.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field

from decoders.model_info import ModelInfo
from decoders.tables import Register, RegisterMap

from sniffer.protocols import modbus_range_ok

MAX_SAMPLES = 512
MAX_DISTINCT = 64
MIN_PAIR_SAMPLES = 4
READS = {0x03: "holding", 0x04: "input"}
WRITES = {0x06: "holding", 0x10: "holding"}
FLOAT_MIN, FLOAT_MAX = 1e-6, 1e9  # |value| of a plausible measurement (0.0 too)
ROUND_MIN = 1e-3  # a round float setpoint is at least this


@dataclass(slots=True)
class RegStats:
    n: int = 0
    lo: int = 0xFFFF
    hi: int = 0
    ups: int = 0
    downs: int = 0
    wraps: int = 0
    last: int | None = None
    distinct: set = field(default_factory=set)
    samples: dict = field(default_factory=dict)  # response number -> value (the first MAX_SAMPLES)
    read: int = 0
    written: int = 0

    def add(self, v: int, seq: int, written: bool) -> None:
        self.n += 1
        self.lo, self.hi = min(self.lo, v), max(self.hi, v)
        if self.last is not None:
            if v > self.last:
                self.ups += 1
            elif v < self.last:
                if self.last >= 0xF000 and v <= 0x0FFF:
                    self.wraps += 1
                else:
                    self.downs += 1
        self.last = v
        if len(self.distinct) <= MAX_DISTINCT:
            self.distinct.add(v)
        if len(self.samples) < MAX_SAMPLES:
            self.samples[seq] = v
        if written:
            self.written += 1
        else:
            self.read += 1


@dataclass(slots=True)
class BlockStats:
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0


@dataclass(slots=True)
class UnitStats:
    requests: int = 0
    responses: int = 0
    exceptions: int = 0


@dataclass
class Guess:
    type: str
    evidence: str
    word_order: str = "big"


def _float(hi: int, lo: int) -> float:
    return struct.unpack(">f", struct.pack(">HH", hi, lo))[0]


def _plausible(x: float) -> bool:
    return x == 0.0 or (math.isfinite(x) and FLOAT_MIN <= abs(x) <= FLOAT_MAX)


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def guess_pair(a: RegStats, b: RegStats) -> Guess | None:
    """float32 or a u32 counter for registers a, a+1 (their stats), from the responses that held both; None
    if the pair does not look like one 32-bit value."""
    seqs = sorted(set(a.samples) & set(b.samples))
    if len(seqs) < MIN_PAIR_SAMPLES:
        return None
    first = [a.samples[s] for s in seqs]
    second = [b.samples[s] for s in seqs]
    for order, his, los in (("big", first, second), ("little", second, first)):
        g = _float_guess(his, los, order)
        if g is not None:
            return g
    # an s32 of small magnitude, high word first: the high word is the low word's sign, in both signs
    if (any(h == 0xFFFF for h in first) and any(h == 0 for h in first)
            and all(h == (0xFFFF if lo & 0x8000 else 0) for h, lo in zip(first, second))):
        vals = [(((h << 16) | lo) ^ 0x80000000) - 0x80000000 for h, lo in zip(first, second)]
        return Guess("s32", f"s32 (high word first) {min(vals)}..{max(vals)}: in all {len(seqs)} samples the high "
                            f"word is the low word's sign (0000H / FFFFH)")
    # a u32 counter, high word first: never falls, and its high word moves exactly when the low word wraps
    vals = [(h << 16) | lo for h, lo in zip(first, second)]
    steps = list(zip(first, first[1:], second, second[1:]))
    wraps = sum(1 for _h0, _h1, l0, l1 in steps if l1 < l0)
    if (wraps and all(y >= x for x, y in zip(vals, vals[1:]))
            and all((h1 != h0) == (l1 < l0) for h0, h1, l0, l1 in steps)):
        return Guess("u32", f"counter: as u32 (high word first) {vals[0]}..{vals[-1]}, never falls; the high "
                            f"word steps exactly when the low word wraps ({wraps}x in {len(seqs)} samples)")
    return None


def _float_guess(his: list[int], los: list[int], order: str) -> Guess | None:
    floats = [_float(h, lo) for h, lo in zip(his, los)]
    if not all(_plausible(x) for x in floats) or all(x == 0.0 for x in floats):
        return None
    nz = [(h, lo) for h, lo, x in zip(his, los, floats) if x != 0.0]
    lo_d = len({lo for _h, lo in nz})
    lo_span = max(lo for _h, lo in nz) - min(lo for _h, lo in nz)
    hi_masked = [h & 0x7FFF for h, _lo in nz]
    hi_d, hi_span = len(set(his)), max(hi_masked) - min(hi_masked)
    which = "high word first" if order == "big" else "low word first"
    fmin, fmax = min(floats), max(floats)
    # the low word jumps (a mantissa's low bits), the high word (sign, exponent, mantissa top) hardly moves
    if lo_d >= 3 and lo_span >= 0x0100 and hi_span <= 0x0600 and hi_d <= lo_d:
        return Guess("f32", f"float32 ({which}) {_fmt(fmin)}..{_fmt(fmax)} in all {len(floats)} samples, "
                                f"while as u16 the low word jumps over {lo_span} ({lo_d} values) and the high "
                                f"word stays within {hi_span}", order)
    # a steady reading: one high word, a low word that jumps between few values, and as float32 the
    # values lie within 1 % of each other (mantissa noise: 0x41B80194 / 0x41B80678 = 23.0008 / 23.0032)
    if (lo_d >= 2 and hi_d == 1 and lo_span >= 0x0100 and fmax != 0.0
            and abs(fmax - fmin) <= 0.01 * max(abs(fmin), abs(fmax))):
        return Guess("f32", f"float32? ({which}) {_fmt(fmin)}..{_fmt(fmax)} in all {len(floats)} samples: one "
                                f"high word, the low word jumps over {lo_span} ({lo_d} values) as mantissa noise "
                                f"does", order)
    # weaker: values that do not move, but are round numbers only as float32 (0x41700000 = 15.0)
    shown = sorted({_fmt(x) for x in floats})
    if (order == "big" and all(lo == 0 for _h, lo in nz) and all(ROUND_MIN <= abs(x) <= FLOAT_MAX for x in floats if x)
            and all(_round(x) for x in floats)):
        return Guess("f32", f"float32? round numbers {', '.join(shown[:6])} as float32 (high word first) in "
                                f"{len(floats)} samples; as u16 {sorted(set(his))[:4]} and 0 (check the manual)",
                     order)
    return None


def _round(x: float) -> bool:
    """A value with at most 3 significant digits (15.0, 0.25, 2300.0): what a float setpoint usually is."""
    return x == 0.0 or float(f"{x:.3g}") == x


def guess_word(s: RegStats) -> Guess:
    """A one-register guess with its evidence."""
    if s.n == 0:
        return Guess("u16", "requested, no value seen (no good response)")
    values = f"{s.n} values"
    if s.lo == s.hi:
        return Guess("u16", f"constant {s.lo} (0x{s.lo:04X}) in {values}")
    if s.downs == 0 and s.ups >= 2 and s.ups >= 8 * s.wraps:  # a u16 counter wraps once per 65536 counts
        wrap = f", wrapped {s.wraps}x" if s.wraps else ""
        return Guess("u16", f"rising (a counter?): rose {s.ups}x, never fell{wrap} ({s.lo}..{s.hi}, {values})")
    neg = [v for v in s.distinct if v >= 0x8000]
    if neg:
        signed = sorted(v - 0x10000 if v >= 0x8000 else v for v in s.distinct)
        if (s.lo < 0x8000 and signed[-1] - signed[0] <= 0x4000 and s.hi - s.lo > 0x8000) or s.lo >= 0xFF00:
            more = "" if len(s.distinct) <= MAX_DISTINCT else " (of the first values)"
            return Guess("s16", f"signed: {signed[0]}..{signed[-1]} as s16{more}, while as u16 {s.lo}..{s.hi} "
                                f"({values})")
    few = ""
    if len(s.distinct) <= 6 and s.n >= 10:
        few = ": " + ", ".join(f"0x{v:04X}" for v in sorted(s.distinct)) + " (an enum or status bits?)"
    distinct = f"{len(s.distinct)}" if len(s.distinct) <= MAX_DISTINCT else f"over {MAX_DISTINCT}"
    return Guess("u16", f"u16 {s.lo}..{s.hi}, {distinct} distinct in {values}{few}")


class Learner:
    """Feed it decoded frames; `to_map` / `to_toml` give the skeleton (see the module doc)."""

    def __init__(self) -> None:
        self.units: dict[int, UnitStats] = {}
        self.blocks: dict[tuple[int, int, int, int], BlockStats] = {}
        self.regs: dict[tuple[int, str, int], RegStats] = {}
        self.frames = 0
        self.first_ns: int | None = None
        self.last_ns = 0
        self._seq = 0

    # ---- feeding -----------------------------------------------------------------------------
    def frame(self, f) -> None:
        self.frames += 1
        if self.first_ns is None:
            self.first_ns = f.t_ns
        self.last_ns = f.t_end_ns
        if f.protocol == "noise" or f.unit is None or not f.crc_ok:
            return
        u = self.units.get(f.unit)
        if u is None:
            u = self.units[f.unit] = UnitStats()
        if f.role == "request":
            u.requests += 1
            self._block(f)
        elif f.role == "response":
            u.responses += 1
            if f.exception is not None:
                u.exceptions += 1
        for i, (table, start, values) in enumerate(f.writes):
            if table not in ("holding", "input"):
                continue
            # a 0x17 (read/write) response records its write part first, then what it read
            written = f.function in WRITES or (f.function == 0x17 and i == 0 and len(f.writes) > 1)
            self._seq += 1
            for k, v in enumerate(values):
                key = (f.unit, table, start + k)
                s = self.regs.get(key)
                if s is None:
                    s = self.regs[key] = RegStats()
                s.add(v, self._seq, written)

    def _block(self, f) -> None:
        fc, adu = f.function, f.adu
        if fc not in READS and fc not in WRITES or len(adu) < 6:
            return
        start = (adu[2] << 8) | adu[3]
        qty = 1 if fc == 0x06 else (adu[4] << 8) | adu[5]
        if fc != 0x06 and not modbus_range_ok(fc, start, qty):
            return  # fields no request of this function can carry: no block, no rows
        key = (f.unit, fc, start, qty)
        b = self.blocks.get(key)
        if b is None:
            b = self.blocks[key] = BlockStats(first_ns=f.t_ns)
            if fc in READS:  # registers asked for but never answered still get a row
                for a in range(start, min(start + qty, 0x10000)):
                    self.regs.setdefault((f.unit, READS[fc], a), RegStats())
        b.count += 1
        b.last_ns = f.t_ns

    # ---- the skeleton ------------------------------------------------------------------------
    def guesses(self) -> dict[int, list[tuple[int, str, Register]]]:
        """address -> [(unit, table, a Register row guessed from that unit's traffic)], pairs merged."""
        out: dict[int, list[tuple[int, str, Register]]] = {}
        by_space: dict[tuple[int, str], list[int]] = {}
        for unit, table, a in self.regs:
            by_space.setdefault((unit, table), []).append(a)
        for (unit, table), addrs in sorted(by_space.items()):
            addrs.sort()
            taken: set[int] = set()
            for a in addrs:
                if a in taken:
                    continue
                s = self.regs[unit, table, a]
                nxt = self.regs.get((unit, table, a + 1))
                g = guess_pair(s, nxt) if nxt is not None and a + 1 <= 0xFFFF else None
                if g is not None and g.evidence.startswith("float32?") and a + 2 <= 0xFFFF:
                    # a weak float guess yields to the pair one register on if that one is stronger or
                    # high word first while this is low word first (the s32 before a float: its low
                    # word and the float's high word look like a steady float low word first)
                    after = self.regs.get((unit, table, a + 2))
                    g2 = guess_pair(nxt, after) if after is not None else None
                    if g2 is not None and (not g2.evidence.startswith("float32?")
                                           or (g.word_order, g2.word_order) == ("little", "big")):
                        g = None  # a stronger guess, or Modbus's own word order, one register on
                if g is not None:
                    taken.add(a + 1)
                    written = s.written + nxt.written
                    read = s.read + nxt.read
                else:
                    g = guess_word(s)
                    written, read = s.written, s.read
                access = "RW" if written and read else "W" if written else "R"
                r = Register(addr=a, id="", name=f"{table} {a:04X}H", type=g.type, access=access,
                             word_order=g.word_order, note=f"u{unit}: {g.evidence}")
                out.setdefault(a, []).append((unit, table, r))
        return out

    def to_map(self, model_id: str, source: str = "") -> RegisterMap:
        """The skeleton map: one row per address and table it was seen in (`table = "holding"` /
        `"input"`: a meter's input 0000H and holding 0000H are two rows, and neither names the other's reads)."""
        rows: dict[int, Register] = {}
        inputs: dict[int, Register] = {}
        for a, all_cands in sorted(self.guesses().items()):
            tables = sorted({t for _u, t, _r in all_cands})
            for table in tables:  # each row names the table it was seen in: a holding read is no input's
                cands = [c for c in all_cands if c[1] == table]
                types = {r.type + r.word_order for _u, _t, r in cands}
                r = Register(addr=a, id="", name=cands[0][2].name, access=_access(c[2].access for c in cands),
                             section=f"learned from {source}" if source else "learned from traffic",
                             table=table)
                if len(types) == 1:
                    r.type, r.word_order, r.words = cands[0][2].type, cands[0][2].word_order, cands[0][2].words
                notes = [c[2].note for c in cands]
                if len(types) > 1:
                    notes.insert(0, "units disagree, left u16")
                r.note = "; ".join(notes)
                (inputs if table == "input" else rows)[a] = r
        # a 32-bit guess must not cover another row of its table: it falls back to u16 there
        for table_rows in (rows, inputs):
            for a in sorted(table_rows):
                r = table_rows[a]
                mine = inputs if r.table == "input" else rows
                others = [mine] + ([inputs] if not r.table else [])
                if r.width > 1 and any(a + k in t for t in others for k in range(1, r.width)):
                    r.note = f"{r.type} guess dropped: {a + 1:04X}H is a register of its own elsewhere; " + r.note
                    r.type, r.word_order, r.words = "u16", "big", 1
        model = ModelInfo(id=model_id, name=f"learned from {source}" if source else "learned from traffic")
        return RegisterMap(model, rows, {}, {}, {}, "", inputs=inputs)

    def summary(self, source: str = "") -> str:
        """The header of the learned file: what was seen, units and blocks (comment lines, no '#')."""
        span = (self.last_ns - (self.first_ns or 0)) / 1e9
        lines = [f"Learned by `sniffer learn` from {source or 'a capture'}: {self.frames} frames, {span:.1f} s.",
                 "A skeleton for the engineer: names are placeholders, each type a guess with its evidence",
                 "in the row's note; check them against the device's manual, then rename.", "", "units:"]
        for unit, u in sorted(self.units.items()):
            lines.append(f"  {unit}: {u.requests} requests, {u.responses} responses, {u.exceptions} exceptions")
        lines.append("blocks (unit, function, registers, how often):")
        for (unit, fc, start, qty), b in sorted(self.blocks.items()):
            what = f"read {READS[fc]}" if fc in READS else f"write {WRITES[fc]}"
            end = f"..{start + qty - 1:04X}H" if qty > 1 else ""
            every = ""
            if b.count > 1:
                every = f", every {(b.last_ns - b.first_ns) / 1e9 / (b.count - 1):.3g} s"
            lines.append(f"  u{unit} fc{fc:02X} {what} {start:04X}H{end} ({qty}): {b.count}x{every}")
        return "\n".join(lines)

    def to_toml(self, model_id: str, source: str = "", path: str = "", regmap: RegisterMap | None = None) -> str:
        """The skeleton (`regmap`, else `to_map`'s) as a registers.toml; `path` (where it goes) makes the
        header's usage line."""
        from decoders.mapformats import to_toml

        use = (f"\nUse it: sniffer replay {source} --model-file {path} --device UNIT={model_id}"
               if source and path else "")
        return to_toml(regmap or self.to_map(model_id, source), header=self.summary(source) + use)


def _access(values) -> str:
    s = set(values)
    if s == {"R"}:
        return "R"
    if s == {"W"}:
        return "W"
    return "RW"
