"""PD-series protocol as data: functions, DATA layouts, CNTR/CNST bits, CFG selectors, parameters.

Source: shared/manuals/pd-series-protocol.txt ("l.N" = line N).  Every row
cites its line so a reviewer can hold it against the manual.  The frame is
ADDR FUNC LEN DATA check (l.64, l.203); these layouts parse DATA only, the
bytes after LEN (ADU offset 3 on).  Checksums stay outside construct
(sniffer.framing.crc).  Interpreted Structs, only `this`-free fixed layouts.

Reading of LEN (the manual contradicts itself, see NOTES.md): LEN counts the
bytes between LEN and the check.  In 01H/02H the DATA starts with the
parameter number (the manual calls it "FUNC", l.97), so "one word -> LEN=3,
one byte -> LEN=2" (l.107, l.181) is the same rule.  Decoding is by the
number of DATA bytes actually present (`LAYOUTS[(function, role)][n]`, in
layouts.py: the construct part, imported when the first PD frame is decoded); the
framer flags a LEN that disagrees (`pd.len.mismatch`).
"""

from __future__ import annotations

from dataclasses import dataclass

REQ, RSP = "request", "response"


# ---- functions (l.75-91) and error replies (l.111, l.125, l.153) -------------
@dataclass(frozen=True, slots=True)
class Function:
    code: int
    name: str
    line: int
    broadcast: str  # what unit 0 means for it (l.99, l.119, l.133, l.161)


FUNCTIONS = {f.code: f for f in (
    Function(0x01, "read parameter", 77, "no answer (l.99): a broadcast read is useless"),
    Function(0x02, "write parameter", 79, "written by every inverter, no reply (l.119)"),
    Function(0x03, "control", 81, "obeyed by every inverter, no reply (l.133)"),
    Function(0x04, "read status", 83, "no reply (l.161): a broadcast read is useless"),
    Function(0x05, "write frequency", 85, "not stated by the manual"),
    Function(0x08, "loop test", 91, "not stated by the manual"),
)}
BROADCAST_READS = frozenset({0x01, 0x04})


@dataclass(frozen=True, slots=True)
class ErrorReply:
    code: int  # the wire function byte; the manual has no separate error-code byte
    answers: tuple[int, ...]
    name: str
    line: int


ERRORS = {e.code: e for e in (
    ErrorReply(0x81, (0x01, 0x02), "parameter not available or setting rejected", 109),  # l.109-111, l.123-125
    ErrorReply(0x83, (0x03,), "control command not accepted", 151),  # l.151-153
)}


# ---- CNTR (l.137-140) and CNST (l.146-149) ------------------------------------
@dataclass(frozen=True, slots=True)
class Bit:
    bit: int
    name: str  # construct field name
    label: str  # the manual's label
    line: int


CNTR_BITS = (
    Bit(0, "run", "run", 140), Bit(1, "forward", "for", 140), Bit(2, "reverse", "rev", 140),
    Bit(3, "stop", "stop", 140), Bit(4, "r_f", "r/f", 140), Bit(5, "jog", "jog", 140),
    Bit(6, "jog_forward", "jogf", 140), Bit(7, "jog_reverse", "jogr", 140),
)
# l.149 prints "r/f" twice (bits 2 and 5).  Our reading: bits 0-2 echo the command
# (run, jog, r/f) and bits 3-5 the drive's actual state (running, jogging, r/f).
CNST_BITS = (
    Bit(0, "run", "run", 149), Bit(1, "jog", "jog", 149), Bit(2, "r_f_command", "r/f (bit 2)", 149),
    Bit(3, "running", "running", 149), Bit(4, "jogging", "jogging", 149),
    Bit(5, "r_f_running", "r/f (bit 5)", 149), Bit(6, "braking", "Braking", 149),
    Bit(7, "track_start", "Track start", 149),
)


def bits_text(bits: tuple[Bit, ...], value: int) -> str:
    on = [b.label for b in bits if (value >> b.bit) & 1]
    return " ".join(on) if on else "none"


# ---- CFG status selectors (l.165-169) -----------------------------------------
@dataclass(frozen=True, slots=True)
class Status:
    cfg: int
    label: str  # the manual's abbreviation
    name: str
    scale: float | None  # None: the manual gives no scale -> raw value
    unit: str | None
    line: int


# Set F / Out F: 0.01 Hz is inferred from the manual's frequency examples (30.00 Hz =
# 0BB8H, l.189/l.228); the manual gives no scale or unit for any status value.
STATUS = {s.cfg: s for s in (
    Status(0, "Set F", "set frequency", 0.01, "Hz", 167),
    Status(1, "Out F", "output frequency", 0.01, "Hz", 167),
    Status(2, "Out A", "output current", None, None, 167),
    Status(3, "RoTT", "rotation speed", None, None, 167),
    Status(4, "DCV", "DC bus voltage", None, None, 169),
    Status(5, "ACV", "output AC voltage", None, None, 169),
    Status(6, "Cont", "counter", None, None, 169),
    Status(7, "Tmp", "temperature", None, None, 169),
)}


# ---- parameters the manual describes --------------------------------------------
@dataclass(frozen=True, slots=True)
class Param:
    number: int  # the byte on the wire ("FUNC" in l.97): PDnnn -> nnn
    name: str
    access: str  # "RW", "R" (manual: can't be changed / observed but not set), "?" (not stated)
    line: int
    min: int | None = None
    max: int | None = None
    scale: float = 1.0
    unit: str | None = None
    enum: tuple[tuple[int, str], ...] = ()
    running: bool = False  # "**": may be set during operation (l.335)

    @property
    def id(self) -> str:
        return f"PD{self.number:03d}"


PARAMS = {p.number: p for p in (
    # PD003 is named only in the l.189 example ("write 30.00Hz ... (write to PD003)")
    Param(3, "frequency (named in the l.189 example)", "RW", 189, scale=0.01, unit="Hz"),
    Param(165, "Communication Data Method", "RW", 3, 0, 5, enum=(
        (0, "8N1 for ASCII"), (1, "8E1 for ASCII"), (2, "8O1 for ASCII"),
        (3, "8N1 for RTU"), (4, "8E1 for RTU"), (5, "8O1 for RTU"))),  # l.6-7, l.34-54
    Param(170, "Display Items", "RW", 260, 0, 5, enum=(
        (0, "inverter temperature"), (1, "counter value"), (2, "PID target value"),
        (3, "PID feedback value"), (4, "running time of this power-up (h)"),
        (5, "total running time (h)"))),  # l.265-270
    Param(171, "Display Items Open", "RW", 272, 0, 7),  # l.277: 3 binary bits; the bit table is missing (l.279)
    Param(172, "Fault Clear", "RW", 283, 0, 10, enum=((1, "fault clear"),), running=True),  # l.286
    Param(174, "Rated Current of Inverter", "R", 288, unit="A"),  # l.291 can't be changed
    Param(175, "Inverter Model", "R", 293, 0, 1, enum=((0, "constant torque"), (1, "fan"))),  # l.296
    Param(176, "Inverter Frequency Standard", "R", 298, enum=((0, "50 Hz"), (1, "60 Hz"))),  # l.301
    Param(177, "Fault Record 1", "?", 303),
    Param(178, "Fault Record 2", "?", 304),
    Param(179, "Fault Record 3", "?", 305),
    Param(180, "Fault Record 4", "?", 306),
    Param(181, "Software Version", "R", 310),  # l.313
    Param(182, "Manufacture date", "R", 315),  # l.320 (week, month, year: encoding not given)
    Param(183, "Serial No.", "R", 326),  # l.329
)}


def enum_text(p: Param, raw: int) -> str | None:
    for v, text in p.enum:
        if v == raw:
            return text
    if p.enum and p.number == 172:
        return "no function"  # l.286: "Others have no function"
    return None


MAX_DATA = 25  # l.183: "fifty ASCII at most" = 25 bytes
