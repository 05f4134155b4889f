"""Live capture from a serial port, strictly receive-only.

Passivity is the point of this module: a stray byte on a PLC <-> drive link
can start a motor.  So:

* the port is opened with os.open(O_RDONLY | O_NOCTTY | O_NONBLOCK), never
  through pyserial's Serial (its open() uses O_RDWR and then drives DTR/RTS
  and flushes buffers).  Subclassing it would mean overriding open() and
  most of what it calls, so termios is done directly (serial_port.py); pyserial only
  lends its termios2 ioctl numbers (odd baud rates) and its sysfs walk for
  the adapter's USB identity.  A write on this fd fails with EBADF, and the
  class has no write() at all;
* the tty line discipline can transmit on its own even without a writable
  fd: ECHO echoes received bytes back out, IXOFF sends XOFF when the input
  buffer fills.  Raw mode clears them, and the settings are read back and
  the capture refused if they did not stick (serial_port.py, which `sniffer
  detect` shares).  The one window left is between open() and tcsetattr()
  on a freshly plugged adapter (kernel
  default termios has ECHO on): microseconds, and usb-serial keeps a tty's
  termios across close and reopen while the adapter stays plugged;
* opening a tty raises DTR/RTS (the kernel does it, not us).  Adapters that
  switch their RS-485 driver with RTS instead of automatically would then
  drive the bus: use an auto-direction adapter, or a receive-only one.

One reader thread does every read and every Tick, so the event stream is in
time order by construction; the consumer only drains a queue (a `Hub`).
Several ports (sources/serial_links.py: several links, or the two wires of a
--tap) share one Hub: each port has its own reader thread, and every reader
takes its event's time and queues the event under the Hub's one lock, so the
merged stream is in time order too.

Reads must not come late: a read that comes after the answer has arrived too
holds request and answer together, and the answer has no latency.  The reader
waits in select() without the interpreter, but getting it back after the wake
took up to CPython's switch interval (5 ms) while the decoding thread held it:
on the 115200 stress line (answers ~1 ms after their request) 12-19 % of the
answers came in their request's read.  `open()` lowers the interval to
READER_SWITCH_S for the process (a capture process, see processes/capture.py;
1-3 % then at 0.5 ms; what is left is the scheduler of a loaded machine), and the
reader asks for a real-time priority (reader_priority.py: a woken normal thread
waits for the CPU's running one).  With the reader real-time it never waits for a
CPU (schedstat: 0 us), so what it still waits for is the interpreter: publishing
to viewers glued more answers at a 0.5 ms switch interval than at 0.1 ms, with the capture's CPU
unchanged (benchmarks/HISTORY.md).  Viewers are now served by a
process of its own (processes/publish_sink.py), so all the capture holds for them is a 16 us batch every 50 ms.
And `sniffer live` runs its readers in a process of their own (processes/reader.py), where no decoding
thread shares their interpreter: one preempted while holding it can no longer keep a read waiting.

A read can also come late because the reader stalled (its CPU or the interpreter taken for longer than
the framer's read slack of 50 ms): then the time it takes is not when the bytes came, and a frame whose
rest waited in the tty would look cut by silence.  So the reader says what it saw: a Chunk read after
the port went unseen for longer than STALL_TICKS ticks has `unseen_ns`, reaching back to the last time
it found the port empty (the framer counts silence only from there; normally it looks every tick, and
the key on every read would grow a capture by 2 %), and a Tick, which says "silent until now", goes out
only if nothing is waiting once its time is taken.
"""

from __future__ import annotations

import errno
import os
import select
import sys
import threading
import time
from collections.abc import Iterator

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.line import LineSettings
from sniffer.sources.lowlatency import request_low_latency
from sniffer.events import CaptureError
from sniffer.sources.reader_priority import raise_reader
from sniffer.sources.serial_port import open_read_only
from sniffer.sources.hub import Hub, PortLostError, ReaderEnd  # noqa: F401 - PortLostError: raised here, imported from here

READ_SIZE = 4096
STALL_TICKS = 4  # the port unseen for longer than this many ticks: the reader stalled (a Chunk's unseen_ns)
READER_SWITCH_S = 0.0001  # the longest the reader waits for the interpreter after a read is due
PORT_POLL_S = 0.2  # how often a lost port is looked for, and a live one's path checked
# Errors that mean "the adapter went away", not "this program is broken".
LOST_ERRNOS = {errno.EIO, errno.ENXIO, errno.ENODEV, errno.EBADF}


class SerialSource:
    """Read-only serial capture: `open()`, iterate `events()`, `stop()` from any thread."""

    def __init__(self, port: str, line: LineSettings, *, tick_interval_s: float = 0.005,
                 reconnect: bool = True, low_latency: bool = True, sysfs: str = "/sys",
                 hub: Hub | None = None, link: str = "", channel: str = "") -> None:
        self.port = port
        self.line = line
        self.tick_ns = max(1, int(tick_interval_s * 1e9))
        self.stall_ns = STALL_TICKS * self.tick_ns
        self.reconnect = reconnect
        self.low_latency = low_latency
        self.sysfs = sysfs
        self.info: CaptureInfo | None = None
        self.lost_since_ns: int | None = None  # set while the port is away (for a status line)
        self.losses = 0  # times the port went away (status.PortNotices says each, however short)
        self._fd: int | None = None
        self._rdev: int | None = None
        self.hub = hub or Hub()
        self.link = link  # Chunk/Tick/Gap.link of every event (several links share the hub)
        self.channel = channel  # Chunk.channel: the wire of a tapped link
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self.lost_reason = ""
        self.ignored: dict = {}  # settings the driver dropped and why that is harmless (serial_port.configure)
        self._ended = False

    # -- consumer side -------------------------------------------------------------

    @property
    def fd(self) -> int | None:
        """The descriptor being read (None while the port is away): for inspection only."""
        return self._fd

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        fd = self._open_port()
        sys.setswitchinterval(min(sys.getswitchinterval(), READER_SWITCH_S))  # see the module doc
        t0 = time.monotonic_ns()
        wall = time.time_ns()
        try:
            ll = request_low_latency(fd, self.port, self.sysfs) if self.low_latency else {"requested": False}
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd
        self.info = CaptureInfo(
            source=f"serial:{self.port}", port=self.port, baud=self.line.baud, parity=self.line.parity,
            stopbits=self.line.stopbits, databits=self.line.databits, time_source="read",
            t0_ns=t0, wall_anchor_ns=wall, low_latency=ll,
        )
        if self.ignored:
            self.info.extra["line_ignored"] = dict(self.ignored)
        self._thread = threading.Thread(target=self._run, name=f"serial-reader {self.port}", daemon=True)
        self._thread.start()
        self.info.extra["reader"] = raise_reader(self._thread.native_id)
        return self.info

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        """Chunks, Ticks and Gaps in time order; ends once stop() was called and the queue is drained."""
        self.open()
        if not self._ended:
            self._ended = True
            yield from self.hub.events(1)

    def stop(self) -> None:
        self._stop.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout=5)

    def __enter__(self) -> "SerialSource":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    # -- reader thread -------------------------------------------------------------

    def _run(self) -> None:
        clock, push, link, channel, stall = self.hub.clock, self.hub.push, self.link, self.channel, self.stall_ns
        try:
            last = time.monotonic_ns()  # time of the last event handed out
            # when the port was last seen empty: a time taken before a select or read that then found
            # nothing new, so what comes next came after it (a Chunk's unseen_ns)
            empty = last
            next_path_check = last + int(PORT_POLL_S * 1e9)
            while not self._stop.is_set():
                if self._fd is None:
                    self._wait_for_port()
                    last = empty = time.monotonic_ns()
                    continue
                now = looked = time.monotonic_ns()
                timeout = min(max(0, last + self.tick_ns - now) / 1e9, PORT_POLL_S)
                try:
                    ready, _, _ = select.select([self._fd], [], [], timeout)
                    data = os.read(self._fd, READ_SIZE) if ready else None
                except BlockingIOError:
                    continue
                except OSError as e:
                    if e.errno not in LOST_ERRNOS:
                        raise
                    self._lose(e.strerror or str(e))
                    continue
                if data == b"":  # readable but empty: the tty was hung up
                    self._lose("hang-up (end of file)")
                    continue
                with clock:  # one order of time for every port of the hub
                    now = time.monotonic_ns()  # right after the read: the read's timestamp
                    if data:
                        unseen = now - empty
                        push(Chunk(now, data, None, (), channel, link, unseen if unseen > stall else None))
                        last = now
                        if len(data) < READ_SIZE:  # the read took all there was, after `looked`
                            empty = looked
                        continue
                    empty = looked  # select found nothing after it
                    # a tick says "silent until now", so nothing may be waiting now: the thread can lose its
                    # CPU or wait for the interpreter between select giving up and taking the time, while
                    # the rest of a frame comes (a tick past t3.5 + read slack would then cut it)
                    if now - last >= self.tick_ns and not select.select([self._fd], [], [], 0)[0]:
                        push(Tick(now, link))
                        last = empty = now
                if now >= next_path_check:
                    next_path_check = now + int(PORT_POLL_S * 1e9)
                    gone = self._path_gone()
                    if gone:
                        self._lose(gone)
        except BaseException as e:  # handed to the consumer, raised from events()
            self._error = e
        finally:
            self._close()
            self.hub.push(ReaderEnd(self))

    def _lose(self, reason: str) -> None:
        self._close()
        if not self.reconnect:
            raise PortLostError(f"{self.port}: port lost ({reason})")
        self.lost_since_ns = time.monotonic_ns()
        self.lost_reason = reason
        self.losses += 1
        self.hub.lost(self)

    def _wait_for_port(self) -> None:
        """Poll for the port to come back; one Gap covers the whole outage."""
        lost, reason = self.lost_since_ns, self.lost_reason
        while not self._stop.wait(PORT_POLL_S):
            try:
                fd = self._open_port()
            except CaptureError:
                continue
            back = time.monotonic_ns()
            if self.low_latency:  # a replugged FTDI starts again at 16 ms
                request_low_latency(fd, self.port, self.sysfs)
            self._fd = fd
            self.lost_since_ns = None
            self.hub.lost(self)
            with self.hub.clock:
                self.hub.push(Gap(lost, back, f"port lost ({reason}), reopened", self.link))
            return
        with self.hub.clock:
            self.hub.push(Gap(lost, time.monotonic_ns(), f"port lost ({reason}), capture stopped before it returned",
                              self.link))

    def _path_gone(self) -> str:
        """A vanished or re-pointed port path means the adapter we hold is not the port any more."""
        try:
            rdev = os.stat(self.port).st_rdev
        except FileNotFoundError:
            return "port path vanished"
        except OSError:
            return ""
        return "" if rdev == self._rdev else "port path now names another device"

    def _close(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass

    # -- opening -------------------------------------------------------------------

    def _open_port(self) -> int:
        fd, self._rdev, self.ignored = open_read_only(self.port, self.line)
        return fd
