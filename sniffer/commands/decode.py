"""`sniffer decode HEX...`: frames typed in (hex, or an ASCII frame's characters), decoded."""

from __future__ import annotations

from sniffer.events import CaptureInfo, Chunk
from sniffer.decoding import decode
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import UsageError, report, stream_sink
from sniffer.commands.flags import MAX_BAUD, command_parser, decode_flags, number, stream_flags


def add_parser(subparsers) -> None:
    import argparse

    p = command_parser(
        subparsers, "decode", help="decode frames given as hex, one argument per frame (no timing: "
                                   "no latency or silence verdicts)",
        description="""\
            Decode frames copied from a manual, a log or a scope: one argument per frame.  The frames have no
            time, so nothing is said about latency, timeouts or silences; requests and responses are paired in
            the order given.""",
        examples=["sniffer decode 010300000002C40B 0103040000000A7A34      # a read and its answer",
                  "sniffer decode 020600010BB8DF7B --device 2=tds-v8       # as unit 2, a TDS-V8, reads it",
                  "sniffer decode :010300000001FB --protocol modbus-ascii"])
    p.add_argument("hex", nargs="+", help="frame bytes in hex, e.g. 010300000002C40B; in an ASCII protocol "
                   "also ':' and the frame's characters (:010300000001FB), the characters in hex "
                   "(3A30...0D0A), or the binary frame with its LRC in hex (010300000001FB)")
    p.add_argument("--baud", type=number(int, "baud rate", 1, MAX_BAUD), default=9600, help=argparse.SUPPRESS)
    decode_flags(p, "frames")
    stream_flags(p)


class HexSource:
    """Frames typed in, each one burst on the line with silence between.

    The input has no time: the capture says time source "none", so nothing reports a
    latency, a timeout or a short silence (the times only keep the frames apart: a gap longer
    than any protocol's quiet time, PD's 50 ms included).
    """

    GAP_NS = 100_000_000

    def __init__(self, frames: list[bytes], spec: CaptureSpec) -> None:
        self.frames = frames
        self.line = spec.resolve(None, need_baud=False).line

    def open(self) -> CaptureInfo:
        line = self.line
        return CaptureInfo(source="decode", baud=line.baud, parity=line.parity, stopbits=line.stopbits,
                           time_source="none")

    def events(self):
        line = self.line
        t = 0
        gap = max(10 * line.t35_ns, self.GAP_NS)
        for data in self.frames:
            times = tuple(t + i * line.char_ns for i in range(len(data)))
            yield Chunk(t, data, times)
            t = times[-1] + line.char_ns + gap


_HEX_DIGITS = frozenset("0123456789abcdefABCDEF")


def _hex_bytes(arg: str) -> bytes | None:
    """The bytes an argument of hex digits (spaces allowed) writes, or None if it is not one."""
    t = arg.replace(" ", "")
    if not t or len(t) % 2 or not set(t) <= _HEX_DIGITS:
        return None
    return bytes.fromhex(t)


def text_frame(arg: str) -> bytes:
    """One argument of `decode` in a text (ASCII) protocol, as the characters on the wire.

    * ':0103...' is the frame's characters (CR LF added if missing);
    * hex digits without ':' are bytes: the wire characters in hex when they are printable
      characters holding a ':' (3A3031...0D0A; several frames and junk as they were sent),
      else the frame's binary content (unit, function, data, LRC), sent as ':' + its hex +
      CR LF (so '010300000001FB' and ':010300000001FB' agree).
    Anything else is a usage error (never decoded as garbage).
    """
    t = arg.strip()
    if t.startswith(":"):
        data = t.encode("ascii", "replace")
        return data if data.endswith(b"\r\n") else data + b"\r\n"
    b = _hex_bytes(t)
    if b is None:
        raise UsageError(f"not a frame: {arg[:60]!r} (give ':' and the frame's characters, or its bytes in hex)")
    if b":" in b and all(0x20 <= c < 0x7F or c in b"\r\n" for c in b):
        # the wire characters in hex: one frame or several, junk included, as they were sent
        return b if b.endswith(b"\r\n") or b.count(b":") > 1 else b + b"\r\n"
    return b":" + b.hex().upper().encode() + b"\r\n"


def run(spec: CaptureSpec, args) -> int:
    text = spec.resolve(None, need_baud=False).protocol.text
    frames = []
    for h in args.hex:
        if text:
            data = text_frame(h)
        else:
            t = h.replace(" ", "").replace(":", "")
            try:
                data = bytes.fromhex(t)
            except ValueError:
                raise UsageError(f"not hex: {h[:60]!r}") from None
        if data:
            frames.append(data)
    session = decode(spec, HexSource(frames, spec), [stream_sink(spec, line_buffered=False)], need_baud=False)
    session.run()
    return report(session)
