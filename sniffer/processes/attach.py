"""`sniffer attach`: view a capture that another process publishes (publish.py).

The viewer never touches the port or the MCAP file: it reads the capture's
frame records from the socket and turns them back into Frames for the TUI
(`attach_feed`) or prints them (`run_headless`, text or JSONL).
"""

from __future__ import annotations

import ipaddress
import select
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator

from sniffer.events import CaptureInfo
from sniffer.processes.stream import CONTROL_PREFIX, STREAM_VERSION, Address, parse_address, parse_reads
from sniffer.formats.records import loads
from sniffer.events import CaptureError


def connect(addr: Address, timeout_s: float) -> socket.socket:
    if addr.path is not None:
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        target: object = addr.path
    else:
        s = socket.socket(socket.AF_INET6 if ":" in addr.host else socket.AF_INET, socket.SOCK_STREAM)
        target = (addr.host, addr.port)
    s.settimeout(timeout_s)
    try:
        s.connect(target)
    except OSError as e:
        s.close()
        if isinstance(e, FileNotFoundError):
            why = ("no such socket: no capture is publishing there "
                   "(sniffer live PORT --publish SOCKET, or sniffer serve)")
        elif isinstance(e, ConnectionRefusedError):
            why = "nothing is listening (has the capture ended?)"
        elif isinstance(e, PermissionError):
            why = "permission denied (the socket belongs to another user)"
        else:
            why = f"cannot connect: {e.strerror or e}"
        raise CaptureError(f"{addr}: {why}") from None
    s.settimeout(None)
    return s


class Attachment:
    """A connection to a publishing capture, its header already read.

    `batches()` yields lists of lines (frame records and control lines,
    without the newline); `control(line)` reads a control line and keeps
    what it says (`status`, `skipped`, `ended`).
    """

    def __init__(self, spec: str, *, timeout_s: float = 10.0) -> None:
        self.address = parse_address(spec)
        self.sock = connect(self.address, timeout_s)
        self._buf = b""
        self._first: list[bytes] = []
        try:
            header = self._read_header(timeout_s)
        except BaseException:
            self.sock.close()
            raise
        self.header = header
        self.info = CaptureInfo.from_dict(header.get("info") or {})
        self.label = header.get("label") or self.info.port or self.info.source
        self.capture_path: str | None = header.get("capture_path")
        self.earlier_frames = int(header.get("earlier_frames") or 0)
        self.status: dict = {}
        self.skipped = 0
        self.ended: dict | None = None
        self.frames_received = 0

    def _read_header(self, timeout_s: float) -> dict:
        deadline = time.monotonic() + timeout_s
        while b"\n" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.sock], [], [], left)[0]:
                raise CaptureError(f"{self.address}: no answer within {timeout_s:.0f} s (not a sniffer capture?)")
            data = self.sock.recv(1 << 16)
            if not data:
                raise CaptureError(f"{self.address}: the capture closed the connection at once")
            self._buf += data
        line, _, self._buf = self._buf.partition(b"\n")
        try:
            header = loads(line) if line.startswith(CONTROL_PREFIX) else None
        except ValueError:
            header = None
        if not isinstance(header, dict) or header.get("sniffer") != "header":
            raise CaptureError(f"{self.address}: not a sniffer capture stream")
        if header.get("stream") != STREAM_VERSION:
            raise CaptureError(f"{self.address}: stream version {header.get('stream')} "
                               f"(sniffer {header.get('sniffer_version')}), this viewer reads {STREAM_VERSION}")
        return header

    @property
    def on_this_machine(self) -> bool:
        """The capture runs here (a Unix socket, or TCP to a loopback address): its reads share our CPUs."""
        if self.sock.family == socket.AF_UNIX:
            return True
        try:
            return ipaddress.ip_address(self.sock.getpeername()[0]).is_loopback
        except (OSError, ValueError):
            return False

    def describe(self) -> str:
        i = self.info
        where = f" -> {self.capture_path}" if self.capture_path else ""
        return f"{self.label} at {i.baud or '?'} {i.databits}{i.parity or 'N'}{i.stopbits or 1} {i.protocol}{where}"

    def batches(self, stop: threading.Event | None = None, poll_s: float = 0.2) -> Iterator[list[bytes]]:
        """Lines as they arrive, until the capture closes the connection (or `stop` is set)."""
        sock = self.sock
        buf, self._buf = self._buf, b""
        while stop is None or not stop.is_set():
            if b"\n" in buf:
                *lines, buf = buf.split(b"\n")
                yield lines
            if not select.select([sock], [], [], poll_s)[0]:
                continue
            try:
                data = sock.recv(1 << 20)
            except OSError:
                data = b""
            if not data:
                return
            buf += data

    def control(self, line: bytes) -> dict:
        msg = loads(line)
        kind = msg.get("sniffer")
        if kind == "status":
            self.status = msg
        elif kind == "skipped":
            self.skipped += int(msg.get("frames") or 0)
        elif kind == "end":
            self.ended = self.status = msg
        return msg

    def lost(self) -> str:
        return f"{self.address}: the capture closed the connection without ending (killed?)"

    def close(self) -> None:
        self.sock.close()


def attach_feed(att: Attachment, pause: Callable[[], object] | None = None):
    """A feed(sink, stop) for tui.run.run_tui: the published frames into the TuiSink.  `pause()` is called
    between two lines (processes/cpu_yield.py: a capture on this machine gets the CPU back in between)."""
    from sniffer.formats.records import frame_from_record

    def feed(sink, stop: threading.Event):
        sink.start(att.info)
        sink.capture_path = att.capture_path
        sink.earlier_frames = att.earlier_frames
        t0 = att.info.t0_ns
        try:
            for lines in att.batches(stop):
                frames = []
                for line in lines:
                    if pause is not None:
                        pause()
                    if line.startswith(CONTROL_PREFIX):
                        msg = att.control(line)
                        if msg.get("sniffer") == "reads":  # the byte view's reads, marked by the capture
                            sink.reads(parse_reads(msg, t0))
                        if "bytes_in" in msg:
                            sink.bytes_in = msg["bytes_in"]
                        sink.skipped_frames = att.skipped
                    elif line:
                        frames.append(frame_from_record(loads(line), t0))
                if frames:
                    att.frames_received += len(frames)
                    sink.frames(frames)
        finally:
            att.close()
        if att.ended is None and not stop.is_set():
            raise ConnectionError(att.lost())

    return feed


def run_headless(att: Attachment, fmt: str) -> int:
    """Print the published frames (text lines or the JSONL records as the capture wrote them)."""
    print(f"sniffer: attached to {att.address}: {att.describe()}", file=sys.stderr)
    if att.earlier_frames:
        hint = f" (sniffer replay {att.capture_path} has them)" if att.capture_path else ""
        print(f"sniffer: {att.earlier_frames} earlier frames are not in the backlog{hint}", file=sys.stderr)
    if fmt == "jsonl":
        out = sys.stdout.buffer
        text = None
    else:
        from sniffer.formats.text import TextSink
        from sniffer.formats.records import frame_from_record

        out = sys.stdout
        text = TextSink(out)
        text.start(att.info)
    t0 = att.info.t0_ns
    try:
        for lines in att.batches():
            records = []
            for line in lines:
                if line.startswith(CONTROL_PREFIX):
                    msg = att.control(line)
                    if msg.get("sniffer") == "skipped":
                        print(f"sniffer: {msg.get('frames')} frames skipped (this viewer fell behind)", file=sys.stderr)
                elif line:
                    records.append(line)
            att.frames_received += len(records)
            if text is None:
                if records:
                    out.write(b"\n".join(records) + b"\n")
            else:
                for line in records:
                    text.frame(frame_from_record(loads(line), t0))
            (text or out).flush()
    finally:
        if text is not None:
            text.flush()  # lines held back for a batched write
        att.close()
    if att.ended is None:
        print(f"sniffer: error: {att.lost()}", file=sys.stderr)
        return 1
    e = att.ended
    print(f"sniffer: capture ended: {e.get('frames')} frames, {e.get('bytes_in')} bytes, "
          f"{e.get('noise_bytes')} noise bytes; this viewer got {att.frames_received}", file=sys.stderr)
    return 0
