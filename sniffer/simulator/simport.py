"""A simulated serial port on a virtual clock: what `sniffer detect` hears from a simulated line,
without a pty and without waiting.

It has what detect/listen.py asks of a port (`configure`, `read`, `now`), and
delivers what PtyLine (uartpty.py) writes to a pty, from the same sans-I/O
LiveLine: the line's traffic received by a UART at the settings last
configured, errors marked in band (PARMRK + INPCK).  `read(timeout)` moves the
clock to the next read or by the timeout, so a search that would take ten
seconds on a pty runs in a fraction of that, the same way every time.
"""

from __future__ import annotations

from collections import deque

from sniffer.line import LineSettings
from sniffer.sources.parmrk import InputFlags
from sniffer.sources.pty_settings import PortSettings
from sniffer.simulator.bus import simulate
from sniffer.simulator.received import LiveLine
from sniffer.simulator.scenario import Scenario

MARKED = InputFlags(parmrk=True, inpck=True)


class SimulatedPort:
    def __init__(self, scenario: Scenario, line: LineSettings, seed: int = 1, *, duration_s: float = 120.0,
                 resync: str = "edge", start_s: float = 0.0) -> None:
        self.line = LiveLine(simulate(scenario, line, duration_s, seed), line, resync)
        self.t = int(start_s * 1e9)
        self.settings: PortSettings | None = None
        self.configured: list[LineSettings] = []  # every setting asked for, in order
        self._pending: deque[tuple[int, bytes]] = deque()

    def configure(self, rx: LineSettings) -> None:
        self.settings = PortSettings(rx, MARKED)
        self.configured.append(rx)
        # what was received before is flushed; from now on the UART receives at the new setting
        self._pending = deque(self.line.retune(self.settings, self.t))

    def now(self) -> int:
        return self.t

    def read(self, timeout_s: float) -> bytes:
        deadline = self.t + int(timeout_s * 1e9)
        while True:
            due = self._pending[0][0] if self._pending else None
            start = self.line.next_t_ns
            if start is None or start > min(deadline, due if due is not None else deadline):
                break
            self.t = max(self.t, start)
            self._pending.extend(self.line.step(self.settings))
        if self._pending and self._pending[0][0] <= deadline:
            due, data = self._pending.popleft()
            self.t = max(self.t, due)
            return data
        self.t = deadline
        return b""

    def close(self) -> None:
        pass
