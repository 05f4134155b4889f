"""Modbus PDU layouts in construct: the reference for every standard function.

Each entry maps (function, role) to a compiled construct Struct that parses
the PDU body: the bytes after the function code and before the CRC.  The CRC
is checked outside construct (sniffer.framing.crc).  Only `this.*` expressions are
used, never lambdas, so the layouts stay compilable.

We parse with the interpreted (uncompiled) Structs: construct 2.10's
compiled `Bytes(this.n)` returns fewer bytes than asked without an error,
which would hide exactly the short frames a sniffer must flag.  Interpreted
parsing costs ~15 us, so the hot layouts (01-06, 0F, 10: nearly all traffic)
are read from the ADU in place by the decoder (decoder.py); `test_generic_inline`
asserts that both readings agree, on random bodies and on every reference
vector.  The decoder imports this module when it first meets a function code
without an in-place reader (importing construct costs 8 MB of RSS and 40 ms: a
capture of common traffic never pays it).
"""

from __future__ import annotations

from construct import (
    Array,
    Bytes,
    Construct,
    GreedyBytes,
    Int8ub,
    Int16ub,
    Struct,
    this,
)

from .names import EXCEPTION_NAMES, FUNCTION_NAMES  # noqa: F401 - the names, with the layouts

REQ, RSP = "request", "response"

ReadRequest = Struct("address" / Int16ub, "quantity" / Int16ub)
ReadBitsResponse = Struct("byte_count" / Int8ub, "status" / Bytes(this.byte_count))
ReadRegistersResponse = Struct(
    "byte_count" / Int8ub, "values" / Array(this.byte_count // 2, Int16ub)
)
WriteSingle = Struct("address" / Int16ub, "value" / Int16ub)
WriteMultipleCoilsRequest = Struct(
    "address" / Int16ub, "quantity" / Int16ub, "byte_count" / Int8ub,
    "values" / Bytes(this.byte_count),
)
WriteMultipleRegistersRequest = Struct(
    "address" / Int16ub, "quantity" / Int16ub, "byte_count" / Int8ub,
    "values" / Array(this.byte_count // 2, Int16ub),
)
WriteMultipleResponse = Struct("address" / Int16ub, "quantity" / Int16ub)
Empty = Struct()
ExceptionStatus = Struct("status" / Int8ub)
Diagnostics = Struct("sub_function" / Int16ub, "data" / GreedyBytes)
CommEventCounter = Struct("status" / Int16ub, "event_count" / Int16ub)
CommEventLog = Struct(
    "byte_count" / Int8ub, "status" / Int16ub, "event_count" / Int16ub,
    "message_count" / Int16ub, "events" / Bytes(this.byte_count - 6),
)
ReportServerId = Struct("byte_count" / Int8ub, "data" / Bytes(this.byte_count))
FileRecord = Struct("byte_count" / Int8ub, "data" / Bytes(this.byte_count))
MaskWrite = Struct("address" / Int16ub, "and_mask" / Int16ub, "or_mask" / Int16ub)
ReadWriteRequest = Struct(
    "read_address" / Int16ub, "read_quantity" / Int16ub,
    "write_address" / Int16ub, "write_quantity" / Int16ub,
    "byte_count" / Int8ub, "values" / Array(this.byte_count // 2, Int16ub),
)
FifoRequest = Struct("address" / Int16ub)
FifoResponse = Struct(
    "byte_count" / Int16ub, "fifo_count" / Int16ub, "values" / Array(this.fifo_count, Int16ub)
)
DeviceIdRequest = Struct("mei_type" / Int8ub, "read_code" / Int8ub, "object_id" / Int8ub)
DeviceIdResponse = Struct(
    "mei_type" / Int8ub, "read_code" / Int8ub, "conformity" / Int8ub,
    "more_follows" / Int8ub, "next_object_id" / Int8ub, "number_of_objects" / Int8ub,
    "objects" / Array(
        this.number_of_objects,
        Struct("id" / Int8ub, "length" / Int8ub, "value" / Bytes(this.length)),
    ),
)
ExceptionBody = Struct("code" / Int8ub)

_LAYOUTS = {
    (0x01, REQ): ReadRequest, (0x01, RSP): ReadBitsResponse,
    (0x02, REQ): ReadRequest, (0x02, RSP): ReadBitsResponse,
    (0x03, REQ): ReadRequest, (0x03, RSP): ReadRegistersResponse,
    (0x04, REQ): ReadRequest, (0x04, RSP): ReadRegistersResponse,
    (0x05, REQ): WriteSingle, (0x05, RSP): WriteSingle,
    (0x06, REQ): WriteSingle, (0x06, RSP): WriteSingle,
    (0x07, REQ): Empty, (0x07, RSP): ExceptionStatus,
    (0x08, REQ): Diagnostics, (0x08, RSP): Diagnostics,
    (0x0B, REQ): Empty, (0x0B, RSP): CommEventCounter,
    (0x0C, REQ): Empty, (0x0C, RSP): CommEventLog,
    (0x0F, REQ): WriteMultipleCoilsRequest, (0x0F, RSP): WriteMultipleResponse,
    (0x10, REQ): WriteMultipleRegistersRequest, (0x10, RSP): WriteMultipleResponse,
    (0x11, REQ): Empty, (0x11, RSP): ReportServerId,
    (0x14, REQ): FileRecord, (0x14, RSP): FileRecord,
    (0x15, REQ): FileRecord, (0x15, RSP): FileRecord,
    (0x16, REQ): MaskWrite, (0x16, RSP): MaskWrite,
    (0x17, REQ): ReadWriteRequest, (0x17, RSP): ReadRegistersResponse,
    (0x18, REQ): FifoRequest, (0x18, RSP): FifoResponse,
    (0x2B, REQ): DeviceIdRequest, (0x2B, RSP): DeviceIdResponse,
}

LAYOUTS: dict[tuple[int, str], Construct] = _LAYOUTS
EXCEPTION_LAYOUT: Construct = ExceptionBody
