"""The publisher process: serves a capture's stream (processes/stream.py) to its viewers.

Run as `python -m sniffer.processes.publisher` by PublishSink (processes/publish_sink.py),
which hands it the listening socket (bound, not listening yet) and a pipe.
The capture sends, over that pipe, length-prefixed pickles (processes/pipes.pipe_message):

    ("start", info dict, label, capture path, t0_ns)   then it listens
    ("batch", frames, reads)            frames: (index, size, link, noise, JSON record); reads: Chunk's fields
    ("end",)                            the end of the capture (EOF says the same)

Why a process: the asyncio loop, the read marking and the socket I/O held the
capture's interpreter a fraction of a millisecond every batch, and the reader waited for it
(publishing, with nobody viewing, glued more answers than headless).
Here they cost the capture nothing.  A late viewer first gets the last
`backlog` records, then the last reads (RING_READS, for the byte view), then
the live stream; a viewer that falls behind has reads dropped and frames
skipped (and is told how many frames).  Nothing here touches the serial port.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import socket
import sys
import threading
from collections import deque

from sniffer import __version__
from sniffer.processes.pipes import read_messages
from sniffer.events import Chunk
from sniffer.processes.cpu_yield import GiveWay, give_cpu
from sniffer.formats.outputs import readable
from sniffer.analysis.reads import RING_READS, ReadMarker
from sniffer.processes.stream import STREAM_VERSION, control, read_item, reads_line

# below the capture (it only loses what viewers see when it is behind), above the viewers (nice 19)
PUBLISHER_NICE = 10


def take_now(queue: deque) -> list:
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


class PublishServer:
    """The viewers of one capture.  A thread reads the capture's pipe into deques; the asyncio loop
    distributes what came every `tick_s` and writes to the viewers."""

    def __init__(self, sock: socket.socket, pipe_fd: int, *, backlog: int = 100_000, viewer_queue: int = 20_000,
                 tick_s: float = 0.05, status_interval_s: float = 1.0, linger_s: float = 2.0) -> None:
        self.sock = sock
        self.pipe_fd = pipe_fd
        self.viewer_queue = viewer_queue
        self.tick_s = tick_s
        self.status_interval_s = status_interval_s
        self.linger_s = linger_s
        self.unix_path = sock.getsockname() if sock.family == socket.AF_UNIX else None
        self.label = ""
        self.capture_path: str | None = None
        self.info: dict = {}
        self._t0 = 0
        self._new: deque[tuple] = deque()  # the pipe thread appends, the loop pops
        self._chunks: deque[Chunk] = deque()
        self._marker = ReadMarker()
        self._backlog: deque[bytes] = deque(maxlen=max(backlog, 0))
        self._read_backlog: deque[bytes] = deque(maxlen=RING_READS)  # read_item()s
        self._viewers: set[_Viewer] = set()
        self._tasks: set[asyncio.Task] = set()
        self.bytes_in = 0
        self.frames = 0
        self.frames_in = 0  # frames the pipe brought (the give-way's "frames come in")
        self._give_way: GiveWay | None = None
        self.noise_bytes = 0
        self._end: bytes | None = None
        self._ended = threading.Event()  # the capture ended (its end message or EOF)

    def wait_start(self) -> bool:
        """Read the pipe up to the start message; False if the capture ended without one."""
        self._messages = read_messages(self.pipe_fd)
        for msg in self._messages:
            if msg[0] == "start":
                _, self.info, self.label, self.capture_path, self._t0 = msg
                return True
            if msg[0] == "end":
                return False
        return False

    def _pipe(self) -> None:
        """The pipe thread: the capture's batches into the deques, until its end."""
        try:
            for msg in self._messages:
                if msg[0] == "batch":
                    _, frames, reads = msg
                    self._chunks.extend(Chunk(*r) for r in reads)
                    self._new.extend(frames)
                    self.frames_in += len(frames)
                    give_cpu()  # this thread gets no SIGALRM (the main thread does): it gives way itself
                elif msg[0] == "end":
                    break
        finally:
            self._ended.set()

    def run(self) -> None:
        """Serve until the capture's end.  Like a viewer, this process gives way while frames come in
        (processes/cpu_yield.py): its loop's bursts (the reads marked and encoded, the viewers' writes) would otherwise
        keep the tty's flush work, and so the capture's reads, waiting on a kernel that preempts nothing."""
        threading.Thread(target=self._pipe, name="capture-pipe", daemon=True).start()
        with GiveWay(lambda: self.frames_in) as self._give_way:
            asyncio.run(self._main())

    async def _main(self) -> None:
        if self.unix_path is not None:
            server = await asyncio.start_unix_server(self._on_viewer, sock=self.sock)
        else:
            server = await asyncio.start_server(self._on_viewer, sock=self.sock)
        loop = asyncio.get_running_loop()
        if self._give_way is not None:
            self._give_way.watch_loop(loop)
        next_status = loop.time() + self.status_interval_s
        while not self._ended.is_set():
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
        self._unlink()  # no new viewer from now on; those connected take what is queued, for at most linger_s
        if self._tasks:
            _, late = await asyncio.wait(self._tasks, timeout=self.linger_s)
            for t in late:
                t.cancel()
            if late:
                await asyncio.wait(late)
        await asyncio.sleep(0)  # let the aborted transports close

    def _unlink(self) -> None:
        if self.unix_path:
            with contextlib.suppress(OSError):
                os.unlink(self.unix_path)

    def _stats(self) -> dict:
        size = None
        if self.capture_path:
            with contextlib.suppress(OSError):
                size = os.path.getsize(readable(self.capture_path)[0])  # its part file while it is written
        return {"frames": self.frames, "bytes_in": self.bytes_in, "noise_bytes": self.noise_bytes,
                "capture_bytes": size}

    def _distribute(self, end: bool = False) -> None:
        # what is there now; the pipe thread keeps appending
        chunks, frames = take_now(self._chunks), take_now(self._new)
        reads = self._marked_reads(chunks, frames, end)
        if frames:
            lines = []
            for _index, size, _link, noise, record in frames:
                if noise:
                    self.noise_bytes += size
                lines.append(record + b"\n")
            self.frames += len(lines)
            self._backlog.extend(lines)
            for v in self._viewers:
                v.push(lines)
        if reads:  # after the frames their bytes went to
            line = reads_line(reads)
            for v in self._viewers:
                v.push_control(line)

    def _marked_reads(self, chunks: list[Chunk], frames: list[tuple], end: bool) -> list[bytes]:
        """The reads whose frames have all settled, encoded (and kept for late viewers)."""
        marker = self._marker
        reads = []
        for c in chunks:
            self.bytes_in += len(c.data)
            reads += marker.chunk(c)
        for index, size, link, _noise, _record in frames:
            reads += marker.frame(index, size, link)
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
        header = control("header", stream=STREAM_VERSION, label=self.label, info=self.info,
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
            # cancelled after linger_s (a viewer that stopped reading): the task ends normally, or asyncio's
            # stream callback reports the cancellation as an error with a traceback
            pass
        finally:
            self._viewers.discard(v)
            self._tasks.discard(asyncio.current_task())
            t = writer.transport
            if not t.is_closing() or t.get_write_buffer_size():
                t.abort()  # cancelled (linger over): drop what a stalled viewer never took


def main(argv: list[str]) -> int:
    """argv: socket fd, pipe fd, ready fd, then backlog, viewer_queue, tick_s, status_interval_s, linger_s."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C is the capture's: it ends us through the pipe
    sock_fd, pipe_fd, ready_fd = (int(x) for x in argv[:3])
    backlog, viewer_queue = int(argv[3]), int(argv[4])
    tick_s, status_s, linger_s = (float(x) for x in argv[5:8])
    with contextlib.suppress(OSError):
        os.nice(PUBLISHER_NICE)
    sock = socket.socket(fileno=sock_fd)
    server = PublishServer(sock, pipe_fd, backlog=backlog, viewer_queue=viewer_queue, tick_s=tick_s,
                           status_interval_s=status_s, linger_s=linger_s)
    try:
        if not server.wait_start():  # the capture never started (its port did not open): nobody to serve
            return 0
        sock.listen(100)
        os.write(ready_fd, b"r")
        os.close(ready_fd)
        server.run()
    finally:
        sock.close()
        server._unlink()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
