"""A terminal that went away under the App: its window closed, or its pty's other end, without a SIGHUP.

A terminal sends SIGHUP to the programs it controls when it closes (run.py ends the App on it), but a pty
that is not the process's controlling terminal (a command started by another program on a pty of its own)
only reads as hung up: Textual's input thread then reads end-of-file in a loop, and the viewer spun at a
full core, a live capture under it running on with nobody to see or stop it.  The App looks at its
terminal at every poll tick (TerminalWatch.gone) and quits as on SIGHUP: a live capture is stopped as
Ctrl-C stops it, its MCAP closed and kept.
"""

from __future__ import annotations

import os
import select


class TerminalWatch:
    """POLLHUP on the terminal the App reads (nothing is read: pending keys stay where they are)."""

    def __init__(self, fd: int | None) -> None:
        self._poll = None
        if fd is not None and os.isatty(fd) and hasattr(select, "poll"):
            self._poll = select.poll()
            self._poll.register(fd, select.POLLHUP)

    def gone(self) -> bool:
        if self._poll is None:
            return False
        return any(ev & (select.POLLHUP | select.POLLERR | select.POLLNVAL) for _, ev in self._poll.poll(0))
