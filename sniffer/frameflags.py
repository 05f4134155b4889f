"""What kind of problem a frame shows, as bits: the TUI's colours and columns, the filter language's flags.

One definition for every reader: the store keeps these bits per row (a column),
the frame list colours rows by them, and `sniffer.filterlang` tests them (`err`,
`crc`, `exc`, `timeout`, `fault`, `noise`, `warn`) on a frame or on the column.
"""

from __future__ import annotations

from .frame import Frame

F_ERROR = 1  # an error annotation or bad CRC
F_WARN = 2  # a warning annotation
F_EXC = 4  # exception response
F_TIMEOUT = 8  # request without (timely) response
F_NOISE = 16
F_FAULT = 32  # the drive reports a fault or alarm (model.fault / model.alarm): a problem of the machine
F_CRC = 64  # the CRC / LRC does not match (also F_ERROR)
F_PROBLEM = F_ERROR | F_WARN | F_EXC | F_TIMEOUT | F_NOISE | F_FAULT
FAULT_CODES = frozenset({"model.fault", "model.alarm"})
TIMEOUT_CODES = frozenset({"pair.timeout", "pair.no_response"})


def frame_flags(f: Frame) -> int:
    fl = 0
    if f.protocol == "noise":
        fl |= F_NOISE
    if f.crc_ok is False:
        fl |= F_ERROR | F_CRC
    if f.exception:
        fl |= F_EXC
    for a in f.annotations:
        if a.code in FAULT_CODES:  # the drive's own trip, not a fault of the line: its own colour
            fl |= F_FAULT
        elif a.severity == "error":
            fl |= F_ERROR
        elif a.severity == "warning":
            fl |= F_WARN
        if a.code in TIMEOUT_CODES:
            fl |= F_TIMEOUT
    return fl
