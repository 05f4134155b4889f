"""What kind of problem a frame shows, as bits: the TUI's colours and columns, the filter language's flags.

One definition for every reader: the store keeps these bits per row (a column),
the frame list colours rows by them, and `sniffer.filterlang` tests them (`err`,
`crc`, `exc`, `timeout`, `fault`, `noise`, `warn`) on a frame or on the column.
"""

from __future__ import annotations

from decoders.registry import code_book
from sniffer.codes import ALARM_CAT, FAULT_CAT, TIMEOUT_CAT
from sniffer.frame import Frame

F_ERROR = 1  # an error annotation or bad CRC
F_WARN = 2  # a warning annotation
F_EXC = 4  # exception response
F_TIMEOUT = 8  # a request that got no response (category timeout: the unit figures' `timeouts`)
F_NOISE = 16
F_FAULT = 32  # the drive reports a fault or an alarm (categories fault, alarm): a problem of the machine
F_CRC = 64  # the CRC / LRC does not match (also F_ERROR)
F_PROBLEM = F_ERROR | F_WARN | F_EXC | F_TIMEOUT | F_NOISE | F_FAULT
FAULT_CODES = code_book().in_category(FAULT_CAT, ALARM_CAT)
TIMEOUT_CODES = code_book().in_category(TIMEOUT_CAT)
_FLAG = {code: F_FAULT if cat in (FAULT_CAT, ALARM_CAT) else F_TIMEOUT for code, cat in code_book().categories.items()
         if cat in (FAULT_CAT, ALARM_CAT, TIMEOUT_CAT)}


def frame_flags(f: Frame) -> int:
    fl = 0
    if f.protocol == "noise":
        fl |= F_NOISE
    if f.crc_ok is False:
        fl |= F_ERROR | F_CRC
    if f.exception:
        fl |= F_EXC
    for a in f.annotations:
        flag = _FLAG.get(a.code, 0)
        if flag == F_FAULT:  # the drive's own trip, not a fault of the line: its own colour
            fl |= F_FAULT
            continue
        fl |= flag
        if a.severity == "error":
            fl |= F_ERROR
        elif a.severity == "warning":
            fl |= F_WARN
    return fl
