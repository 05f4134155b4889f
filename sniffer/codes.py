"""Annotation codes: each declared once, beside the stage that emits it; the JSONL, the TUI and the tests speak them.

Each code is a constant `Code` (its dotted name, severity, sentence and the category it counts as);
stages create annotations from the constant, so a misspelt code is a NameError, not a silent new
string.  This module declares the core codes: Modbus framing and decoding, the line, pairing, the
registry.  What is specific to a protocol or a drive model is declared next to its framer or decoder,
as sigrok's decoders declare their annotations: sniffer/framing/pd.py (`pd.*` framing),
decoders/pd_series (`pd.*`), decoders/table_decoder.py (`model.*` checks against a manual's map),
decoders/tds_v8 (`tds.*`), decoders/teco_a510 (`a510.*`).  Framers (`framer.codes`, collected by
sniffer.protocols) and decoders (`Decoder.codes`, on the class) say which codes they may emit, and
`CodeBook` assembles the table from those declarations; tests/test_codes.py checks that every `Code`
in the tree is in it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

INFO = "info"
WARNING = "warning"
ERROR = "error"
SEVERITIES = (INFO, WARNING, ERROR)


# What a code counts as in the per-unit figures (sniffer.analysis.unitfigures), the status file's error counts,
# the report's error series, the frame flags the TUI colours and filters by, and the dataset's query
# presets: each code says it in its declaration (`Code.category`, wherever the code is declared), and the code
# book (`CodeBook.categories`, `in_category`) gathers them, so no module keeps a list of codes.
TIMEOUT_CAT = "timeout"  # the request got no response (whatever ended the wait, but the capture's end)
END_OF_CAPTURE_CAT = "end_of_capture"  # the capture ended while the request waited: not a timeout
LATE_CAT = "late"  # answered after the unit's response timeout: a response, not a timeout
RETRY_CAT = "retry"  # the master repeated an unanswered request
ORPHAN_CAT = "orphan"  # a response no pending request explains
EXCEPTION_CAT = "exception"  # an exception response (once per frame: its code's detail notes have none)
FAULT_CAT = "fault"  # the drive reports a fault (trip)
ALARM_CAT = "alarm"  # the drive reports an alarm (warning)
NOISE_CAT = "noise"
UART_CAT = "uart"  # a byte received with a framing or parity error
GAP_CAT = "gap"  # the capture itself was interrupted
T15_CAT = "t15"
T35_CAT = "t35"
CATEGORIES = (TIMEOUT_CAT, END_OF_CAPTURE_CAT, LATE_CAT, RETRY_CAT, ORPHAN_CAT, EXCEPTION_CAT, FAULT_CAT, ALARM_CAT,
              NOISE_CAT, UART_CAT, GAP_CAT, T15_CAT, T35_CAT)


@dataclass(slots=True, frozen=True)
class Code:
    code: str
    severity: str
    text: str
    category: str | None = None  # one of CATEGORIES: what the code counts as (None: only itself)


class Annotation(NamedTuple):
    """Immutable; a NamedTuple because a frozen dataclass costs ~1 us to build, on the hot path."""

    code: str
    severity: str
    detail: str
    start: int  # byte span inside the frame, [start, end)
    end: int

    def to_dict(self) -> dict:
        return {
            "code": self.code,
            "severity": self.severity,
            "detail": self.detail,
            "span": [self.start, self.end],
        }


def note(code: Code, detail: str, start: int, end: int) -> Annotation:
    return Annotation(code.code, code.severity, detail, start, end)


def note_in(code: Code, detail: str, start: int, end: int, size: int) -> Annotation:
    """An annotation whose span is clamped into a frame of `size` bytes (never empty)."""
    end = min(end, size)
    start = min(start, end - 1) if end > 0 else 0
    return Annotation(code.code, code.severity, detail, max(0, start), max(end, 1))


# --- framing -----------------------------------------------------------------
CRC_MISMATCH = Code("modbus.crc.mismatch", ERROR, "CRC does not match the frame's bytes")
CRC_UNPROVEN = Code(
    "modbus.crc.unproven", ERROR,
    "the CRC (or LRC) matches, but over a byte received with a UART error: no proof, the frame is not taken as good",
)
CRC_ONE_BYTE = Code(
    "modbus.crc.one_byte", INFO,
    "one damaged byte explains the CRC mismatch: the first (address) byte or a CRC byte, and which value it had",
)
LENGTH_MISMATCH = Code(
    "modbus.length.mismatch", ERROR, "frame length does not match its function code / byte count"
)
LENGTH_TRUNCATED = Code(
    "modbus.length.truncated", ERROR, "frame ends before the length its header announces (cut off)"
)
FUNCTION_UNKNOWN = Code(
    "modbus.function.unknown", WARNING, "function code neither public nor user-defined in the Modbus spec"
)
FUNCTION_USER = Code(
    "modbus.function.user_defined", INFO, "user-defined function code (65-72, 100-110): shown raw"
)
UNIT_RESERVED = Code("modbus.unit.reserved", WARNING, "unit address 248-255 is reserved")
STRUCTURE_MISMATCH = Code(
    "modbus.structure.mismatch", WARNING, "the frame's bytes contradict the structure its function code defines"
)
T15_VIOLATION = Code(
    "modbus.timing.t15", WARNING, "silence inside the frame longer than 1.5 character times", T15_CAT
)
T35_SHORT = Code(
    "modbus.timing.t35", INFO, "frame started less than 3.5 character times after the previous one", T35_CAT
)
UART_FRAMING = Code("uart.framing_error", ERROR, "byte received with a framing error (bad stop bit)", UART_CAT)
UART_PARITY = Code("uart.parity_error", ERROR, "byte received with a parity error", UART_CAT)
NOISE = Code("noise.bytes", WARNING, "bytes that form no frame", NOISE_CAT)
SOURCE_GAP = Code("source.gap", WARNING, "capture interrupted (adapter lost); bytes may be missing", GAP_CAT)

# --- pairing -----------------------------------------------------------------
NO_RESPONSE = Code("pair.no_response", WARNING, "request got no response", TIMEOUT_CAT)
TIMEOUT = Code("pair.timeout", WARNING, "no response within the unit's response timeout", TIMEOUT_CAT)
LATE_RESPONSE = Code("pair.late_response", WARNING, "response arrived after the response timeout", LATE_CAT)
ORPHAN_RESPONSE = Code("pair.orphan_response", WARNING, "response with no matching request", ORPHAN_CAT)
RETRY = Code("pair.retry", WARNING, "request repeats an unanswered request (master retry)", RETRY_CAT)
BROADCAST_RESPONSE = Code(
    "pair.broadcast_response", ERROR, "a unit answered a broadcast request (unit 0)"
)
BROADCAST = Code("pair.broadcast", INFO, "broadcast request: no response expected")
BROADCAST_FUNCTION = Code(
    "pair.broadcast.function", WARNING, "unit 0 addressed with a function a broadcast cannot carry (a read)"
)
ROLE_AMBIGUOUS = Code(
    "pair.role.ambiguous", INFO, "the frame fits a request and a response; pairing context chose, and says how"
)
PAIR_MISMATCH = Code(
    "pair.mismatch", ERROR, "response does not match its request (echo, address, count)"
)
END_OF_CAPTURE = Code("pair.end_of_capture", INFO, "capture ended before a response could arrive", END_OF_CAPTURE_CAT)

# --- decoding ----------------------------------------------------------------
EXCEPTION = Code("modbus.exception", WARNING, "exception response", EXCEPTION_CAT)
EXCEPTION_UNLISTED = Code(
    "modbus.exception.unlisted", WARNING,
    "exception code not in the unit's table (its manual's, or the Modbus standard's for a generic unit)",
)
DECODE_SHORT = Code("modbus.decode.short", ERROR, "frame too short for its function code")
BYTE_COUNT_ODD = Code(
    "modbus.byte_count.odd", WARNING, "register read answer with an odd byte count: its last byte is no register"
)
BITS_PADDING = Code(
    "modbus.bits.padding", WARNING, "coil/input bits beyond the requested quantity are set (the spec pads with 0)"
)
NO_REQUEST_CONTEXT = Code(
    "modbus.decode.no_request", INFO, "register addresses unknown: response has no request"
)
MODEL_MISMATCH = Code("model.mismatch", WARNING, "traffic does not look like the configured model")

# --- Modbus ASCII framing (ascii_framer) ------------------------------------------
ASCII_NO_CRLF = Code("modbus.ascii.no_crlf", WARNING, "ASCII frame not ended by CR LF")
ASCII_BAD_HEX = Code("modbus.ascii.bad_hex", ERROR, "ASCII frame holds characters that are not hex digits")

# --- generic Modbus decoding (decoders/generic) ------------------------------------
COIL_VALUE = Code("modbus.coil.value", ERROR, "write single coil value must be FF00 or 0000")
QUANTITY = Code("modbus.quantity.range", ERROR, "quantity outside the range the Modbus spec allows")

# --- the decoder registry (decoders/registry.py) ------------------------------------
MODEL_GUESS = Code("model.guess", INFO, "unit's model guessed from its traffic (no device map entry)")
MODEL_GUESS_WITHDRAWN = Code(
    "model.guess.withdrawn", WARNING, "an earlier model guess withdrawn: the traffic rules that model out"
)
# what the stages outside framers and decoders emit (pipeline, pairer, registry); framers and
# decoders declare their own in `codes` (protocols.py collects the framers')
CORE_CODES: tuple[Code, ...] = (
    SOURCE_GAP, NO_RESPONSE, TIMEOUT, LATE_RESPONSE, ORPHAN_RESPONSE, RETRY, BROADCAST_RESPONSE,
    BROADCAST, PAIR_MISMATCH, END_OF_CAPTURE, DECODE_SHORT, MODEL_MISMATCH, MODEL_GUESS,
    BROADCAST_FUNCTION, ROLE_AMBIGUOUS, MODEL_GUESS_WITHDRAWN,
)
# the Modbus RTU framer's codes (LineBuffer's own are the UART, t1.5 and noise ones)
LINE_CODES: tuple[Code, ...] = (UART_FRAMING, UART_PARITY, T15_VIOLATION, NOISE, CRC_UNPROVEN)
RTU_CODES: tuple[Code, ...] = LINE_CODES + (
    CRC_MISMATCH, CRC_ONE_BYTE, LENGTH_MISMATCH, FUNCTION_UNKNOWN, FUNCTION_USER, UNIT_RESERVED, T35_SHORT,
    STRUCTURE_MISMATCH, LENGTH_TRUNCATED,
)


class CodeBook:
    """Every code a set of stages may emit: the core ones plus what each framer and decoder declares.

    Built from the declarations (a framer's or a decoder's `codes`), never from a list kept here:
    `decoders.registry.code_book()` is the book of everything that ships, a registry's `codebook`
    the book of its own decoders.  A code declared twice, differently, is refused.
    """

    def __init__(self, *groups: tuple[Code, ...]) -> None:
        self._codes: dict[str, Code] = {}
        for group in (CORE_CODES, *groups):
            for c in group:
                known = self._codes.get(c.code)
                if known is not None and known != c:
                    raise ValueError(f"annotation code {c.code} declared twice, differently")
                self._codes[c.code] = c
        # code -> what it counts as (the codes with a category only)
        self.categories: dict[str, str] = {c.code: c.category for c in self._codes.values() if c.category}

    def __contains__(self, code: str) -> bool:
        return code in self._codes

    def get(self, code: str) -> Code | None:
        return self._codes.get(code)

    def all(self) -> list[Code]:
        return sorted(self._codes.values(), key=lambda c: c.code)

    def in_category(self, *categories: str) -> frozenset[str]:
        """The codes that count as any of `categories`."""
        return frozenset(code for code, cat in self.categories.items() if cat in categories)
