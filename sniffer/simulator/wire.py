"""What crossed the simulated wire: a WireFrame and the kinds and faults it names (bus.py makes them; faults.py and
wirefaults.py change them)."""

from __future__ import annotations

from dataclasses import dataclass

KIND_REQUEST = "request"
KIND_RESPONSE = "response"
KIND_EXCEPTION = "exception"
KIND_BROADCAST = "broadcast"
KIND_NOISE = "noise"
KIND_CORRUPTED = "corrupted"
KINDS = (KIND_REQUEST, KIND_RESPONSE, KIND_EXCEPTION, KIND_BROADCAST, KIND_NOISE, KIND_CORRUPTED)

# why a frame is special (WireFrame.fault)
FAULT_CRC = "crc"  # a byte was hit on the wire; the CRC no longer matches
FAULT_TIMEOUT = "timeout"  # request that got no answer at all
FAULT_EXCEPTION = "exception"  # exception response (see exception_code)
FAULT_BROADCAST_ANSWER = "broadcast_answer"  # a slave answered unit 0 (a firmware bug)
FAULT_NOISE = "noise"


@dataclass(frozen=True, slots=True)
class WireFrame:
    """One frame as it crossed the wire, plus what really happened."""

    t_ns: int  # start bit of the first byte
    t_end_ns: int  # end of the last byte's stop bit
    raw: bytes  # as on the wire (CRC or LRC included, corrupted if kind == corrupted; ASCII: the characters)
    byte_t_ns: tuple[int, ...]  # start bit of every byte
    kind: str  # one of KINDS
    unit: int | None = None  # address byte as sent (None for noise)
    function: int | None = None
    expects_answer: bool = False  # the master waits for a reply to it
    answered: bool = False  # a reply (good or damaged) followed
    txn: int = -1  # exchange number: a request, its retries and the reply share it
    attempt: int = 0  # 0 = first try, 1.. = retries with the same bytes
    role: str = ""  # what the frame was meant to be (differs from kind when corrupted)
    fault: str = ""  # FAULT_*, "" for an ordinary frame
    exception_code: int | None = None
    turnaround_ns: int | None = None  # reply: silence after the request's last stop bit
    late: bool = False  # reply drawn from the unit's slow turnaround range
    flags: tuple[tuple[int, str], ...] = ()  # UART errors a logic analyzer would flag

    @property
    def crc_valid(self) -> bool:
        return self.kind not in (KIND_CORRUPTED, KIND_NOISE)
