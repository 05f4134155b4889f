"""`sniffer detect P1 P2 ...`: several ports settled at once, each listened to in a process of its own.

    results = settle(opened, listen_one)      # opened: {link name: SerialPort}, each opened already

The command opens every port first (read-only, its first candidate set), so a port that cannot be
opened ends it in one line before any listening starts.  Then a child process per port, forked so
it inherits its port, listens as `detect PORT` does and sends back what the report needs
(`PortResult`, plain data: the table, the verdict's line, the [[links]] table for the bus file).  A
process each, not a thread: detect times the characters by when the reads come, and a reader thread
that waits for the interpreter while another port's bytes are framed would blur that.  The children
ignore Ctrl-C (the command's to handle: it ends them) and end with it if it is killed outright.
"""

from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Callable
from dataclasses import dataclass, field

from sniffer.capture.busfile import BusFile
from sniffer.detect.report import headline, link_table, table, units
from sniffer.detect.search import Verdict
from sniffer.events import CaptureError
from sniffer.processes.parent_death import worker_args, worker_ends_with_parent


@dataclass
class PortResult:
    port: str
    name: str  # its [[links]] name
    status: str = "error"  # the verdict's status (search.Verdict), or "error": the port failed while listening
    headline: str = ""  # the verdict in one line (or what went wrong)
    table: list[str] = field(default_factory=list)
    decided_s: float = 0.0
    tried: int = 0  # settings listened at
    units: list[str] = field(default_factory=list)
    link: BusFile | None = None  # its [[links]] table (settled ports)
    notes: list[str] = field(default_factory=list)  # the comment lines after it

    @property
    def settled(self) -> bool:
        return self.status in ("certain", "fits", "stop bits")


def result_of(v: Verdict, port: str, name: str) -> PortResult:
    r = PortResult(port, name, v.status, headline(v, port), table(v) if v.status != "no traffic" else [],
                   v.decided_s, len(v.windows))
    if r.settled:
        from sniffer.detect.models import Naming

        named = Naming().feed(v.best.answers, v.best.best.protocol)
        r.units = units(v.best, named)
        r.link, r.notes = link_table(v, name, port, named)
    return r


def settle(opened: dict, listen_one: Callable[[object], Verdict]) -> list[PortResult]:
    """Every opened port (`{name: SerialPort}`) listened to by `listen_one(port)` in a child process of its own,
    all at once; their results in the order given."""
    ctx = multiprocessing.get_context("fork")  # the child inherits its port's open descriptor
    children = []
    try:
        for name, port in opened.items():
            rx, tx = ctx.Pipe(duplex=False)
            child = ctx.Process(target=_child, args=(port, name, listen_one, tx, *worker_args()), name=f"detect {name}",
                                daemon=True)
            child.start()
            tx.close()
            port.close()  # the child's now
            children.append((name, port.path, child, rx))
        out = []
        for name, path, child, rx in children:
            try:
                out.append(rx.recv())
            except EOFError:  # it died without a word
                child.join(5)
                out.append(PortResult(path, name, headline=f"{path}: its listening process ended "
                                                           f"(exit status {child.exitcode})"))
            child.join(5)
        return out
    finally:
        for _, _, child, rx in children:
            if child.is_alive():
                child.terminate()
                child.join(2)
            rx.close()
        for port in opened.values():
            port.close()


def _child(port, name: str, listen_one, tx, parent_pid: int, from_main_thread: bool) -> None:
    worker_ends_with_parent(parent_pid, from_main_thread)  # a detect killed outright: no port listened to on
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        res = result_of(listen_one(port), port.path, name)
    except CaptureError as e:
        res = PortResult(port.path, name, headline=str(e))
    except Exception as e:  # noqa: BLE001 - said as the port's one line, the others go on
        res = PortResult(port.path, name, headline=f"{port.path}: {type(e).__name__}: {e}")
    tx.send(res)
    tx.close()
