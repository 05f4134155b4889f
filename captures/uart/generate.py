"""Write the byte-CSV fixtures of this folder: lines whose UART flagged a byte (captures/README.md lists them).

Hand-built wire timing (per-byte start-bit times, as a logic analyzer gives them), the
shapes seen on real lines: a line driver that leaves a 0x00 with a framing error right
after each request when it turns off, a retry after a unit kept silent, a response whose
first 8 bytes pass as a CRC-valid request, a 7E1 ASCII line with a parity error.

    python captures/uart/generate.py      # rewrites the *.bytes.csv next to this file
"""

from __future__ import annotations

from pathlib import Path

from sniffer.framing.crc import crc_bytes, lrc
from sniffer.events import Chunk
from sniffer.line import LineSettings
from sniffer.formats.bytecsv.reader import write_byte_csv

HERE = Path(__file__).resolve().parent
GLITCH = "framing"  # the flag of the 0x00 a turning-off driver leaves


def rtu(hex_body: str) -> bytes:
    body = bytes.fromhex(hex_body)
    return body + crc_bytes(body)


class Wire:
    """Bytes on one line, characters back to back inside a burst; `flags` per byte of a burst."""

    def __init__(self, line: LineSettings) -> None:
        self.char = line.char_ns
        self.t = 10_000_000
        self.chunks: list[Chunk] = []

    def burst(self, data: bytes, flags: dict[int, str] | None = None, after_chars: float = 0.0) -> None:
        self.t += round(after_chars * self.char)
        times = tuple(self.t + k * self.char for k in range(len(data)))
        self.chunks.append(Chunk(times[-1] + self.char, data, times, tuple(sorted((flags or {}).items()))))
        self.t = times[-1] + self.char

    def request(self, data: bytes, glitch: str | None = GLITCH, after_ms: float = 100.0) -> None:
        """A request sent `after_ms` after the last byte, and the driver's turn-off 0x00 right after it."""
        self.t += round(after_ms * 1e6)
        if glitch is None:
            self.burst(data)
        else:
            self.burst(data + b"\x00", {len(data): glitch})

    def response(self, data: bytes, after_chars: float = 3.0) -> None:
        """The answer, `after_chars` of silence after the last byte (a quick slave: under t3.5)."""
        self.burst(data, after_chars=after_chars)


def turnoff_rtu() -> list[Chunk]:
    """Modbus RTU, 9600 8N1, unit 1: every request but the last ends in a flagged 0x00."""
    w = Wire(LineSettings(9600, "N", 1))
    w.request(rtu("010300000001"), after_ms=0)  # third byte 00: no 9-byte reading checks
    w.response(rtu("010302002a"))
    for reg in ("0406", "0410"):  # third byte 04: the request + 0x00 checks as a 9-byte response
        w.request(rtu(f"0103{reg}0001"))
        w.response(rtu("01030204d2"))
    w.request(rtu("010404000002"))  # FC04, two registers: the 9-byte reading even has the right size
    w.response(rtu("01040400010002"), after_chars=4.0)
    w.request(rtu("010304200002"))  # unanswered, then retried
    w.request(rtu("010304200002"), glitch="parity", after_ms=120)  # a parity flag says the same
    w.response(rtu("01030400050006"))
    w.request(rtu("010300000002"))  # answered by a response whose first 8 bytes check as a request
    w.response(bytes.fromhex("01030444ea370a5900"))
    w.request(rtu("010304060001"), glitch=None)  # no turn-off glitch on this one: nothing to mistake
    w.response(rtu("01030204d2"))
    return w.chunks


def turnoff_pd() -> list[Chunk]:
    """PD-series RTU, 9600 8N1: a frame whose LEN counts one byte too many (as the manual prints
    them), then the driver's flagged 0x00: LEN points at that 0x00 and the CRC holds over it."""
    w = Wire(LineSettings(9600, "N", 1))
    quiet = 60e6 / w.char  # the manual's > 50 ms between frames, in characters
    w.request(rtu("010403010000"), after_ms=0)  # read status CFG 1, LEN 03: right
    w.response(rtu("010403010bb8"), after_chars=quiet)
    for _ in range(2):
        w.request(rtu("010404010000"))  # LEN 04 over three data bytes: LEN + 5 ends on the 0x00
        w.response(rtu("010403010bb8"), after_chars=quiet)
    return w.chunks


def flagged_ascii() -> list[Chunk]:
    """Modbus ASCII, 9600 7E1: a line with a parity error on one character whose LRC holds all the
    same, and the turn-off 0x00 after a line's LF."""
    w = Wire(LineSettings(9600, "E", 1, 7))

    def line(adu_hex: str) -> bytes:
        adu = bytes.fromhex(adu_hex)
        return b":" + (adu.hex().upper() + f"{lrc(adu):02X}").encode() + b"\r\n"

    req, rsp = line("010300000001"), line("010302002A")
    w.burst(req)
    w.burst(rsp, after_chars=5)
    w.burst(req + b"\x00", {len(req): GLITCH}, after_chars=100)
    w.burst(rsp, {6: "parity"}, after_chars=5)
    w.burst(req, after_chars=100)
    w.burst(rsp, after_chars=5)
    return w.chunks


FIXTURES = {
    "turnoff-rtu.bytes.csv": turnoff_rtu,
    "turnoff-pd.bytes.csv": turnoff_pd,
    "flagged-ascii.bytes.csv": flagged_ascii,
}


def main() -> None:
    for name, make in FIXTURES.items():
        write_byte_csv(str(HERE / name), make())


if __name__ == "__main__":
    main()
