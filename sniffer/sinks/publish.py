"""Publish a running capture to viewers on a local socket (`--publish`): the stream of stream_format.py.

The capture process owns the port and the MCAP file; any number of viewers
(`sniffer attach`, the browser UI of `sniffer serve`) connect and read.
A late viewer first gets the last `backlog` records, then the last reads
(RING_READS, for the byte view), then the live stream.  The capture thread
only appends frames and reads to deques; a thread of its own marks the reads
with their frames (sniffer.reads), serialises both (once for all viewers) and
does the socket I/O.  A viewer that falls behind has reads dropped and frames
skipped (and is told how many frames); it never makes the capture wait.
Nothing here touches the serial port.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import stat
import threading
from collections import deque

from .. import __version__
from ..events import CaptureInfo, Chunk
from ..frame import Frame
from ..outputs import readable
from ..reads import RING_READS, ReadMarker
from ..records import frame_json
from ..stream_format import STREAM_VERSION, Address, PublishError, control, parse_address, read_item, reads_line
from .base import Sink


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


def _take(queue: deque) -> list:
    """Pop what a deque holds now (another thread may go on appending)."""
    popleft = queue.popleft
    return [popleft() for _ in range(len(queue))]


class _Viewer:
    """One connected viewer: lines waiting to be written, at most `limit` of them."""

    __slots__ = ("ended", "limit", "pending", "skipped", "wake")

    def __init__(self, limit: int) -> None:
        self.pending: list[bytes] = []
        self.limit = limit
        self.skipped = 0
        self.wake = asyncio.Event()
        self.ended = False

    def push(self, lines: list[bytes]) -> None:
        room = self.limit - len(self.pending)
        if room <= 0:
            self.skipped += len(lines)
            return
        if self.skipped:
            self.pending.append(control("skipped", frames=self.skipped))
            self.skipped = 0
        self.pending.extend(lines[:room])
        self.skipped += max(0, len(lines) - room)
        self.wake.set()

    def push_control(self, line: bytes) -> None:
        """A line it may miss when it is behind (status, reads)."""
        if len(self.pending) < self.limit:
            self.pending.append(line)
            self.wake.set()

    def end(self, line: bytes) -> None:
        """The last line, after what is queued (and the count of what was not)."""
        if self.skipped:
            self.pending.append(control("skipped", frames=self.skipped))
            self.skipped = 0
        self.pending.append(line)
        self.ended = True
        self.wake.set()

    def take(self) -> list[bytes]:
        out, self.pending = self.pending, []
        return out


class PublishSink(Sink):
    """A pipeline sink that serves the capture's frames to viewers on a socket.

    The socket is claimed at construction (so a bad address fails before the
    port is opened) and accepts viewers from `start()`; `close()` sends the
    end line, lets viewers take what is queued (up to `linger_s`), removes
    the socket file.  `close()` is idempotent and also releases a sink that
    was never started.
    """

    def __init__(self, address: str | Address, *, label: str = "", capture_path: str | None = None,
                 backlog: int = 100_000, viewer_queue: int = 20_000, tick_s: float = 0.05,
                 status_interval_s: float = 1.0, linger_s: float = 2.0) -> None:
        self.address = address if isinstance(address, Address) else parse_address(address)
        self.label = label
        self.capture_path = os.path.abspath(capture_path) if capture_path else None
        self.viewer_queue = viewer_queue
        self.tick_s = tick_s
        self.status_interval_s = status_interval_s
        self.linger_s = linger_s
        self._sock: socket.socket | None = _bind(self.address)
        if self.address.path is None and self.address.port == 0:  # tcp:HOST:0 -> the port given
            self.address = Address(host=self.address.host, port=self._sock.getsockname()[1])
        self._new: deque[Frame] = deque()  # capture thread appends, publisher thread pops
        self._chunks: deque[Chunk] = deque()  # likewise: the reads, marked with their frames there
        self._marker = ReadMarker()  # publisher thread
        self._backlog: deque[bytes] = deque(maxlen=max(backlog, 0))
        self._read_backlog: deque[bytes] = deque(maxlen=RING_READS)  # read_item()s
        self._viewers: set[_Viewer] = set()
        self._tasks: set[asyncio.Task] = set()
        self._t0 = 0
        self.info: CaptureInfo | None = None
        self.bytes_in = 0  # capture thread
        self.frames = 0  # publisher thread: frames serialised so far
        self.noise_bytes = 0
        self._end: bytes | None = None  # the end line, once the capture has ended
        self._ready = threading.Event()
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False

    # ---------------------------------------------------------------- Sink protocol (capture thread)
    def start(self, info: CaptureInfo) -> None:
        self.info = info
        self._t0 = info.t0_ns
        self._thread = threading.Thread(target=self._serve, name="publish", daemon=True)
        self._thread.start()
        self._ready.wait(5)

    def raw(self, event) -> None:
        if type(event) is Chunk:
            self.bytes_in += len(event.data)
            self._chunks.append(event)

    def frame(self, frame: Frame) -> None:
        self._new.append(frame)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._closing.set()
        if self._thread is not None:
            self._thread.join(self.linger_s + 5)
        else:
            self._release()

    def __enter__(self) -> PublishSink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- publisher thread
    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        try:
            loop.run_until_complete(self._main())
        finally:
            loop.close()
            self._ready.set()
            self._release()

    def _release(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None
            if self.address.path is not None:
                with contextlib.suppress(OSError):
                    os.unlink(self.address.path)

    async def _main(self) -> None:
        if self.address.path is not None:
            server = await asyncio.start_unix_server(self._on_viewer, sock=self._sock)
        else:
            server = await asyncio.start_server(self._on_viewer, sock=self._sock)
        self._ready.set()
        loop = asyncio.get_running_loop()
        next_status = loop.time() + self.status_interval_s
        while not self._closing.is_set():
            await asyncio.sleep(self.tick_s)
            self._distribute()
            if loop.time() >= next_status:
                next_status = loop.time() + self.status_interval_s
                line = control("status", **self._stats())
                for v in self._viewers:
                    v.push_control(line)
        self._distribute(end=True)
        self._end = control("end", **self._stats())
        for v in self._viewers:
            v.end(self._end)
        server.close()
        if self._tasks:  # viewers take what is queued for them, for at most linger_s
            _, late = await asyncio.wait(self._tasks, timeout=self.linger_s)
            for t in late:
                t.cancel()
            if late:
                await asyncio.wait(late)
        await asyncio.sleep(0)  # let the aborted transports close

    def _stats(self) -> dict:
        size = None
        if self.capture_path:
            with contextlib.suppress(OSError):
                size = os.path.getsize(readable(self.capture_path)[0])  # its part file while it is written
        return {"frames": self.frames, "bytes_in": self.bytes_in, "noise_bytes": self.noise_bytes,
                "capture_bytes": size}

    def _distribute(self, end: bool = False) -> None:
        chunks, frames = _take(self._chunks), _take(self._new)  # what is there now; the capture keeps appending
        reads = self._marked_reads(chunks, frames, end)
        if frames:
            t0 = self._t0
            lines = []
            for f in frames:
                if f.protocol == "noise":
                    self.noise_bytes += len(f.raw)
                lines.append(frame_json(f, t0) + b"\n")
            self.frames += len(lines)
            self._backlog.extend(lines)
            for v in self._viewers:
                v.push(lines)
        if reads:  # after the frames their bytes went to
            line = reads_line(reads)
            for v in self._viewers:
                v.push_control(line)

    def _marked_reads(self, chunks: list[Chunk], frames: list[Frame], end: bool) -> list[bytes]:
        """The reads whose frames have all settled, encoded (and kept for late viewers)."""
        marker = self._marker
        reads = []
        for c in chunks:
            reads += marker.chunk(c)
        for f in frames:
            reads += marker.frame(f.index, len(f.raw), f.link)
        if end:
            reads += marker.flush()
        t0 = self._t0
        items = [read_item(r, t0) for r in reads]
        self._read_backlog.extend(items)
        return items

    async def _on_viewer(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._tasks.add(asyncio.current_task())
        # the backlog snapshot and the registration happen with no await between: no frame lost or doubled
        backlog = list(self._backlog)
        v = _Viewer(self.viewer_queue)
        self._viewers.add(v)
        if self._end is not None:  # connected as the capture ended
            v.end(self._end)
        reads = list(self._read_backlog)
        header = control("header", stream=STREAM_VERSION, label=self.label, info=self.info.to_dict(),
                         capture_path=self.capture_path, earlier_frames=self.frames - len(backlog),
                         backlog_frames=len(backlog), backlog_reads=len(reads), sniffer_version=__version__)
        try:
            writer.write(header)
            for i in range(0, len(backlog), 2000):
                writer.write(b"".join(backlog[i:i + 2000]))
                await writer.drain()
            for i in range(0, len(reads), 2000):
                writer.write(reads_line(reads[i:i + 2000]))
                await writer.drain()
            del backlog, reads
            while True:
                v.wake.clear()
                lines = v.take()
                if lines:
                    writer.write(b"".join(lines))
                    await writer.drain()
                elif v.ended:
                    break
                else:
                    await v.wake.wait()
            writer.close()
            await writer.wait_closed()  # the transport has sent what it holds
        except (ConnectionError, OSError):
            pass  # the viewer went away
        except asyncio.CancelledError:
            # cancelled by close() after linger_s (a viewer that stopped reading): the task ends normally,
            # or asyncio's stream callback reports the cancellation as an error with a traceback
            pass
        finally:
            self._viewers.discard(v)
            self._tasks.discard(asyncio.current_task())
            t = writer.transport
            if not t.is_closing() or t.get_write_buffer_size():
                t.abort()  # cancelled (linger over): drop what a stalled viewer never took
