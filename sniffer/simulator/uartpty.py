"""A simulated line served on a pseudo-terminal as a UART at the sniffer's settings would receive it.

    with PtyLine(get_scenario("default"), LineSettings(19200, "E", 1)) as line:
        line.link("/tmp/line0")           # optional: a symlink to the pty for other programs
        line.play(stop_event)             # blocks; `sniffer detect /tmp/line0` in another process

PtyBus (ptybus.py) hands the sniffer the bytes as they were sent.  PtyLine puts
them on a bit-level wire at the line's true settings (uart.py, received.LiveLine)
and, before every write, reads back what the sniffer set its end of the pty to
(pty_settings.py: baud, parity, stop bits, data bits, and whether it asked for
PARMRK/INPCK marks); a change mid-frame takes effect from then on.
A UART at those settings receives the wire: bytes re-sampled at the wrong baud,
parity and framing errors, breaks; its tty hands them over as n_tty would
(parmrk.tty_bytes, with the marks where they were asked for).  The characters go
out when the UART completes them, in the writes of a USB adapter whose latency
timer is 1 ms (received.GRID_NS: a reader sees how fast characters come).  What the
sniffer writes to its end is counted (`bytes_received_from_sniffer`: 0 for a
passive sniffer).
"""

from __future__ import annotations

import os
import threading
import time
from collections import deque

from sniffer.line import LineSettings
from sniffer.sources.pty_settings import PortSettings, read_settings
from sniffer.simulator.bus import simulate
from sniffer.simulator.ptybus import PtyBus
from sniffer.simulator.received import LiveLine
from sniffer.simulator.scenario import Scenario

FOREVER_S = 10 * 365 * 86400.0
AHEAD_NS = 20_000_000  # reads are worked out this long before they are due


class PtyLine:
    def __init__(self, scenario: Scenario, line: LineSettings, seed: int = 1, duration_s: float = 0.0,
                 resync: str = "edge") -> None:
        self.scenario = scenario
        self.line = line
        self.seed = seed
        self.duration_s = duration_s if duration_s > 0 else FOREVER_S
        self.resync = resync
        self.bus = PtyBus()
        self.port = self.bus.port
        self.frames_sent = 0
        self.overrun_bytes = 0  # bytes no one read in time (the pty's buffer was full)
        self.settings: PortSettings | None = None  # what the sniffer's end was set to, last seen
        self._link: str | None = None

    def __enter__(self) -> "PtyLine":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def bytes_received_from_sniffer(self) -> int:
        self.bus.drain()
        return self.bus.bytes_received_from_sniffer

    def link(self, path: str) -> None:
        """A symlink at `path` to the pty (removed by close())."""
        os.symlink(self.port, path)
        self._link = path

    def play(self, stop: threading.Event | None = None) -> None:
        """Play the scenario in real time until its duration ends or `stop` is set."""
        stop = stop or threading.Event()
        line = LiveLine(simulate(self.scenario, self.line, self.duration_s, self.seed), self.line, self.resync)
        offset = time.monotonic_ns() - (line.next_t_ns or 0)  # wall clock = bus time + offset
        reads: deque[tuple[int, bytes]] = deque()
        if not self._read_settings():
            return
        checked = 0  # bus time the settings were last seen unchanged
        while True:
            # the reads are worked out AHEAD_NS before they are due (the model takes CPU time), and
            # worked out again if the sniffer sets its end to something else meanwhile: from the last
            # time the old settings were seen (it changed them somewhere since)
            now = time.monotonic_ns() - offset
            while line.next_t_ns is not None and line.known_ns < now + AHEAD_NS:
                reads.extend(line.step(self.settings, keep_from_ns=checked))
            self.frames_sent = line.frames_sent
            if not reads:
                if line.next_t_ns is None:
                    break
                if not self.bus.wait_until(offset + line.next_t_ns - AHEAD_NS, stop):
                    return
                continue
            due, data = reads[0]
            if not self.bus.wait_until(offset + due, stop) or not self._read_settings():
                return
            if self.settings != line.settings:
                reads = deque(line.retune(self.settings, checked))
                continue
            checked = due
            reads.popleft()
            self._write(data)
        self.bus.drain()

    def _read_settings(self) -> bool:
        try:
            self.settings = read_settings(self.bus.master_fd)
        except OSError:
            return False  # the pty is gone
        return True

    def _write(self, data: bytes) -> None:
        """A line does not wait for its reader: what the pty cannot take now is lost (an overrun)."""
        while data:
            try:
                data = data[os.write(self.bus.master_fd, data):]
            except BlockingIOError:
                self.overrun_bytes += len(data)
                return

    def close(self) -> None:
        """Hang up, then remove the link: an unplugged adapter's tty hangs up before udev removes its node
        (the other way round, a capture that checked the path in between said "port path vanished")."""
        self.bus.close()
        if self._link is not None:
            try:
                if os.path.islink(self._link):
                    os.remove(self._link)
            except OSError:
                pass
            self._link = None
