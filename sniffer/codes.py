"""Annotation codes: declared once, spoken by the JSONL, the TUI and the tests.

Each code is a constant `Code`; stages create annotations from the constant,
so a misspelt code is a NameError, not a silent new string.  Decoders declare
the codes they may emit (`Decoder.codes`); `CodeBook` collects the core codes
and those of the decoders in one explicit instance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

INFO = "info"
WARNING = "warning"
ERROR = "error"
SEVERITIES = (INFO, WARNING, ERROR)


@dataclass(slots=True, frozen=True)
class Code:
    code: str
    severity: str
    text: str


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
LENGTH_MISMATCH = Code(
    "modbus.length.mismatch", ERROR, "frame length does not match its function code / byte count"
)
FUNCTION_UNKNOWN = Code(
    "modbus.function.unknown", WARNING, "function code neither public nor user-defined in the Modbus spec"
)
FUNCTION_USER = Code(
    "modbus.function.user_defined", INFO, "user-defined function code (65-72, 100-110): shown raw"
)
UNIT_RESERVED = Code("modbus.unit.reserved", WARNING, "unit address 248-255 is reserved")
T15_VIOLATION = Code(
    "modbus.timing.t15", WARNING, "silence inside the frame longer than 1.5 character times"
)
T35_SHORT = Code(
    "modbus.timing.t35", INFO, "frame started less than 3.5 character times after the previous one"
)
UART_FRAMING = Code("uart.framing_error", ERROR, "byte received with a framing error (bad stop bit)")
UART_PARITY = Code("uart.parity_error", ERROR, "byte received with a parity error")
NOISE = Code("noise.bytes", WARNING, "bytes that form no frame")
SOURCE_GAP = Code("source.gap", WARNING, "capture interrupted (adapter lost); bytes may be missing")

# --- pairing -----------------------------------------------------------------
NO_RESPONSE = Code("pair.no_response", WARNING, "request got no response")
TIMEOUT = Code("pair.timeout", WARNING, "no response within the unit's response timeout")
LATE_RESPONSE = Code("pair.late_response", WARNING, "response arrived after the response timeout")
ORPHAN_RESPONSE = Code("pair.orphan_response", WARNING, "response with no matching request")
RETRY = Code("pair.retry", WARNING, "request repeats an unanswered request (master retry)")
BROADCAST_RESPONSE = Code(
    "pair.broadcast_response", ERROR, "a unit answered a broadcast request (unit 0)"
)
BROADCAST = Code("pair.broadcast", INFO, "broadcast request: no response expected")
PAIR_MISMATCH = Code(
    "pair.mismatch", ERROR, "response does not match its request (echo, address, count)"
)
END_OF_CAPTURE = Code("pair.end_of_capture", INFO, "capture ended before a response could arrive")

# --- decoding ----------------------------------------------------------------
EXCEPTION = Code("modbus.exception", WARNING, "exception response")
DECODE_SHORT = Code("modbus.decode.short", ERROR, "frame too short for its function code")
DECODE_ROLE = Code("modbus.decode.role_unknown", INFO, "direction unknown; decoded as both")
NO_REQUEST_CONTEXT = Code(
    "modbus.decode.no_request", INFO, "register addresses unknown: response has no request"
)
MODEL_MISMATCH = Code("model.mismatch", WARNING, "traffic does not look like the configured model")

CORE_CODES: tuple[Code, ...] = tuple(v for v in list(globals().values()) if isinstance(v, Code))


class CodeBook:
    """All codes a pipeline may emit: the core ones plus what each decoder declares."""

    def __init__(self, *groups: tuple[Code, ...]) -> None:
        self._codes: dict[str, Code] = {}
        for group in (CORE_CODES, *groups):
            for c in group:
                known = self._codes.get(c.code)
                if known is not None and known != c:
                    raise ValueError(f"annotation code {c.code} declared twice, differently")
                self._codes[c.code] = c

    def __contains__(self, code: str) -> bool:
        return code in self._codes

    def get(self, code: str) -> Code | None:
        return self._codes.get(code)

    def all(self) -> list[Code]:
        return sorted(self._codes.values(), key=lambda c: c.code)
