"""`sniffer detect`'s listening: the port set to each candidate in turn, read until the search has heard enough.

    verdict = listen(SerialPort("/dev/ttyUSB0"), Search(baud_order(())))

The port is opened once, read-only, exactly as `sniffer live` opens it
(sources/serial_port.py: O_RDONLY, raw, the settings read back), with UART
errors marked in band (PARMRK + INPCK); each candidate is set on the same fd
(no reopening: opening a tty raises DTR/RTS).  Nothing is ever written.
`listen` works on anything with `configure(rx)`, `read(timeout_s)` and `now()`:
the serial port here, or a simulated one (sniffer/simulator/simport.py) whose
clock is virtual, for tests and benchmarks that need no pty and no waiting.
"""

from __future__ import annotations

import os
import select
import time
from collections.abc import Callable

from sniffer.line import LineSettings
from sniffer.sources.lowlatency import request_low_latency
from sniffer.events import CaptureError
from sniffer.sources.serial_port import configure, is_pty, open_read_only
from sniffer.detect.evidence import Evidence
from sniffer.detect.search import Search, Verdict
from sniffer.detect.window import Window

TICK_S = 0.005  # silence is noticed this soon
EVAL_NS = 50_000_000  # how often a listen asks whether it has heard enough
READ_SIZE = 4096
MORE_NS = 500_000_000  # while a unit is not named yet, the follow-up listen asks again this often


class SerialPort:
    """The real port, read-only (see the module doc)."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.fd: int | None = None
        self._pty = False

    def configure(self, rx: LineSettings) -> None:
        if self.fd is None:
            self.fd, rdev, _ = open_read_only(self.path, rx, marks=True)
            self._pty = is_pty(rdev)
            request_low_latency(self.fd, self.path)  # reads as soon as the bytes come: sharper timing
            return
        try:
            configure(self.fd, rx, pty=self._pty, marks=True)
        except CaptureError as e:
            raise CaptureError(f"{self.path}: {e}") from None

    def now(self) -> int:
        return time.monotonic_ns()

    def read(self, timeout_s: float) -> bytes:
        try:
            ready, _, _ = select.select([self.fd], [], [], timeout_s)
            data = os.read(self.fd, READ_SIZE) if ready else b""
        except BlockingIOError:
            return b""
        except OSError as e:
            raise CaptureError(f"{self.path}: port lost ({e.strerror or e})") from None
        if ready and not data:
            raise CaptureError(f"{self.path}: port lost (hang-up)")
        return data

    def close(self) -> None:
        fd, self.fd = self.fd, None
        if fd is not None:
            os.close(fd)


def listen(port, search: Search, *, max_s: float = 60.0, follow_s: float = 0.0,
           on_window: Callable[[Evidence], None] | None = None,
           more: Callable[[Evidence], bool] | None = None, more_s: float = 0.0) -> Verdict:
    """Listen at each candidate the search asks for, until it is done or `max_s` have passed.  A candidate
    found certain is listened to `follow_s` longer, for the units and their poll periods, and then on while
    `more(evidence)` says so (a unit not named yet), up to `more_s` after the verdict in all."""
    start = port.now()
    decided = None
    try:
        while (rx := search.next()) is not None:
            port.configure(rx)
            t = port.now()
            w = Window(rx, t)
            next_eval, until, ev = t + EVAL_NS, None, None
            while True:
                if until is not None and t >= until:
                    if not (more is not None and ev is not None and ev.certain and t - decided < more_s * 1e9
                            and more(w.evidence(t))):
                        break
                    until = t + MORE_NS  # listen a little longer, then ask again
                data = port.read(TICK_S)
                t = port.now()
                if data:
                    w.feed(t, data)
                else:
                    w.tick(t)
                if until is None and t >= next_eval:
                    next_eval = t + EVAL_NS
                    ev = w.evidence(t)
                    if search.window_done(ev) or t - start >= max_s * 1e9:
                        until = t + int(follow_s * 1e9) if ev.certain else t
                        decided = t
            ev = w.evidence(t)
            search.add(ev)
            if on_window is not None:
                on_window(ev)
            if t - start >= max_s * 1e9:
                break
    finally:
        port.close()
    verdict = search.verdict()
    verdict.decided_s = ((decided or port.now()) - start) / 1e9
    return verdict
