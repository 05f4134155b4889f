"""Publish a running capture to viewers on a local socket (`--publish`): the stream of processes/stream.py.

The capture process owns the port and the MCAP file; any number of viewers
(`sniffer attach`, the browser UI of `sniffer serve`) connect and read.  They
are served by a process of its own (processes/publisher.py: the asyncio loop, the
read marking, the socket I/O), so serving them never holds the capture's
interpreter while its reader waits for it.  This sink claims the socket,
starts that process and hands it the frames' records and the reads over a
pipe.  Nothing here touches the serial port.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import stat
import subprocess
import sys
import threading
from collections import deque

from sniffer.events import CaptureInfo, Chunk, read_fields
from sniffer.frame import Frame
from sniffer.processes.pipes import child_env, pipe_message, pipe_size
from sniffer.processes.publisher import take_now
from sniffer.formats.records import frame_json
from sniffer.stderr import say
from sniffer.processes.stream import Address, PublishError, parse_address
from sniffer.sinks.base import Sink

READY_S = 30.0  # the publisher process listens within this after start(), or the capture does not start
PIPE_BYTES = 1 << 20  # the pipe to it: about 13 s of the 115200 stress line's records
MAX_PENDING = 50_000  # frames waiting for it: beyond, it is cut off (it has taken nothing for minutes)


def _bind(addr: Address) -> socket.socket:
    if addr.path is None:
        family = socket.AF_INET6 if ":" in addr.host else socket.AF_INET
        s = socket.socket(family, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((addr.host, addr.port))
        except OSError as e:
            s.close()
            raise PublishError(f"{addr}: cannot listen: {e.strerror or e}") from None
        return s
    path = addr.path
    if os.path.lexists(path):
        if not stat.S_ISSOCK(os.lstat(path).st_mode):
            raise PublishError(f"{path}: exists and is not a socket (not replacing it)")
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
            try:
                probe.connect(path)
            except OSError:  # left over by a capture that was killed: take it over
                os.unlink(path)
            else:
                raise PublishError(f"{path}: another capture is publishing there")
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        s.bind(path)
        os.chmod(path, 0o600)  # only this user's viewers (connecting needs write permission)
    except OSError as e:
        s.close()
        raise PublishError(f"{path}: cannot create socket: {e.strerror or e}") from None
    return s


class PublishSink(Sink):
    """A pipeline sink that serves the capture's frames to viewers on a socket, from a process of its own.

    The socket is claimed at construction (so a bad address fails before the
    port is opened) and the publisher process (processes/publisher.py) started with
    it; from `start()` it accepts viewers.  The capture thread only appends
    frames and reads to deques; a flusher thread hands them over every
    `tick_s`, their records encoded (the MCAP sink's encoding, made once per
    frame).  `close()` sends the end, waits while viewers take what is queued
    (up to `linger_s`), removes the socket file.  `close()` is idempotent and
    also releases a sink that was never started.  A publisher that dies or
    falls `max_pending` frames behind costs the viewers their stream, never
    the capture.
    """

    def __init__(self, address: str | Address, *, label: str = "", capture_path: str | None = None,
                 backlog: int = 100_000, viewer_queue: int = 20_000, tick_s: float = 0.05,
                 status_interval_s: float = 1.0, linger_s: float = 2.0, max_pending: int = MAX_PENDING) -> None:
        self.address = address if isinstance(address, Address) else parse_address(address)
        self.label = label
        self.capture_path = os.path.abspath(capture_path) if capture_path else None
        self.tick_s = tick_s
        self.linger_s = linger_s
        self.max_pending = max_pending
        sock = _bind(self.address)
        if self.address.path is None and self.address.port == 0:  # tcp:HOST:0 -> the port given
            self.address = Address(host=self.address.host, port=sock.getsockname()[1])
        pipe_r, self._pipe = os.pipe()
        ready_w = -1
        try:
            self._ready, ready_w = os.pipe()
            pipe_size(self._pipe, PIPE_BYTES)
            argv = [sys.executable, "-m", "sniffer.processes.publisher", str(sock.fileno()), str(pipe_r), str(ready_w),
                    str(max(backlog, 0)), str(viewer_queue), str(tick_s), str(status_interval_s), str(linger_s)]
            self._proc: subprocess.Popen | None = subprocess.Popen(
                argv, pass_fds=(sock.fileno(), pipe_r, ready_w), stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL, env=child_env())
        except OSError as e:
            os.close(self._pipe)
            with contextlib.suppress(AttributeError, OSError):
                os.close(self._ready)
            self._proc = None
            self._unlink()
            raise PublishError(f"{self.address}: cannot start the publisher process: {e.strerror or e}") from None
        finally:  # the child holds them now
            sock.close()
            os.close(pipe_r)
            if ready_w >= 0:
                os.close(ready_w)
        self._new: deque[Frame] = deque()  # capture thread appends, flusher thread pops
        self._chunks: deque[Chunk] = deque()  # likewise: the reads (the publisher marks them with their frames)
        self._t0 = 0
        self.frames = 0  # flusher thread: frames handed to the publisher so far
        self._cut = False  # the publisher is gone or too far behind: frames are no longer kept for it
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False

    # ---------------------------------------------------------------- Sink protocol (capture thread)
    def start(self, info: CaptureInfo) -> None:
        self._t0 = info.t0_ns
        self._send(pipe_message(("start", info.to_dict(), self.label, self.capture_path, info.t0_ns)))
        ready, _, _ = select.select([self._ready], [], [], READY_S)
        said = os.read(self._ready, 1) if ready else b""
        if said != b"r":
            why = "did not start listening" if not ready else "ended"
            raise PublishError(f"{self.address}: the publisher process {why}")
        self._thread = threading.Thread(target=self._flusher, name="publish", daemon=True)
        self._thread.start()

    def raw(self, event) -> None:
        if type(event) is Chunk and not self._cut:
            self._chunks.append(event)

    def frame(self, frame: Frame) -> None:
        if self._cut:
            return
        self._new.append(frame)
        if len(self._new) > self.max_pending:  # the publisher has taken nothing for a long while
            self._cut_off(f"the publisher fell {len(self._new)} frames behind")

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._closing.set()
        if self._thread is None:
            self._close_pipe()  # never started: it sees the end of the pipe before any start, and ends
        else:  # the flusher sends the rest and the end, and closes the pipe
            self._thread.join(5)
            if self._thread.is_alive():  # stuck writing: the publisher takes nothing
                self._proc.kill()
                self._thread.join(5)
        if self._proc is not None:
            try:
                self._proc.wait(self.linger_s + 5)  # it lets viewers take what is queued, then ends
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        self._close_pipe()
        with contextlib.suppress(OSError):
            os.close(self._ready)
        self._unlink()

    def __enter__(self) -> PublishSink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- flusher thread
    def _flusher(self) -> None:
        while not self._closing.wait(self.tick_s):
            self._flush()
        self._flush()
        if not self._cut:
            self._send(pipe_message(("end",)))
        self._close_pipe()

    def _flush(self) -> None:
        chunks, frames = take_now(self._chunks), take_now(self._new)
        if self._cut or not (chunks or frames):
            return
        t0 = self._t0
        batch = [(f.index, len(f.raw), f.link, f.protocol == "noise", frame_json(f, t0)) for f in frames]
        self.frames += len(batch)
        reads = [read_fields(c) for c in chunks]
        self._send(pipe_message(("batch", batch, reads)))

    def _send(self, data: bytes) -> None:
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(self._pipe, view):]
        except OSError as e:  # EPIPE: it died (a closed pipe after close(): EBADF)
            if not self._closed:
                self._cut_off(f"the publisher process ended ({e.strerror or e})")

    def _cut_off(self, why: str) -> None:
        if not self._cut:
            self._cut = True
            say(f"{why}: viewers get nothing more of this capture (the capture goes on)")
        self._new.clear()
        self._chunks.clear()

    def _close_pipe(self) -> None:
        fd, self._pipe = self._pipe, -1
        if fd >= 0:
            with contextlib.suppress(OSError):
                os.close(fd)

    def _unlink(self) -> None:
        if self.address.path is not None:
            with contextlib.suppress(OSError):
                if stat.S_ISSOCK(os.lstat(self.address.path).st_mode):
                    os.unlink(self.address.path)
