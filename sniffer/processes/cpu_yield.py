"""The viewer of a live capture, and the publisher serving it, hand their CPU back every GIVE_WAY_S while
frames come in.

Why (traced with ftrace on a kernel that preempts nothing on wakeup, preempt=none): a byte written to a
tty (the USB-RS485 adapter's driver, or a pty) reaches the reader through the tty's flush work, a kworker of
the unbound workqueue.  When that kworker is woken onto the CPU where the viewer is drawing, it is not given
the CPU until the viewer's thread blocks or the next tick (4 ms): no reschedule is sent, whatever the
viewer's priority (nice 19 or SCHED_IDLE alike).  The capture's read then comes late, holds the request and
its answer together, and the answer loses its latency.  Any process that runs in ms-long bursts does the
same, and a Textual redraw is such a burst; the same work cut into 0.2 ms slices keeps the flush work's
wait that short (benchmarks/HISTORY.md has the measurements).

How: while frames come in and the App's loop works (not while it waits: watch_loop), an interval timer sends
this process SIGALRM every GIVE_WAY_S; the kernel interrupts the running thread's CPU to deliver it, and the
handler, sched_yield(2) itself installed in C, yields that CPU: whatever the kernel queued behind the
drawing runs, the drawing goes on after.  (A Python handler would wait for the interpreter, run in the main
thread only, and write every signal to asyncio's wakeup fd.)  The kernel gives the signal to the main
thread, so the feed thread (the records from the capture's socket) calls give_cpu() itself between two
records.  A thread of our own that takes the interpreter away periodically does not do it: its own wakeup
lands on the drawing's CPU and waits there like the kworker.  Nothing while the line is quiet or the capture
has ended: idle means ~0 CPU.  SA_RESTART, and Python resumes what the signal still interrupts (PEP 475).

What it does not cover: the capture's reader woken behind the viewer between two signals; where the system
grants it, the reader runs SCHED_FIFO (sources/reader_priority.py), which preempts at once.  On a kernel that
preempts on wakeup (a desktop's preempt=voluntary or full) the viewer would not hold the CPU anyway; the
timer then costs its signals only, while the App works and frames come in
(benchmarks/bench_capture_timing.py measures all of it).
"""

from __future__ import annotations

import ctypes
import signal
import threading
from collections.abc import Callable

GIVE_WAY_S = 0.0002  # the longest the viewer's drawing keeps a CPU from the capture while frames come in
QUIET_S = 1.0  # no new frame for this long: the line is quiet, the timer stops
LOOK_S = 0.1  # how often the frame count is looked at


class _SigAction(ctypes.Structure):
    """glibc's struct sigaction (Linux, x86-64 and arm64 alike)."""

    _fields_ = [("sa_handler", ctypes.c_void_p), ("sa_mask", ctypes.c_ulong * 16), ("sa_flags", ctypes.c_int),
                ("sa_restorer", ctypes.c_void_p)]


SA_RESTART = 0x10000000


def _libc():
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.sigaction, libc.sched_yield  # noqa: B018 - both there, or no giving way
        return libc
    except (OSError, AttributeError):
        return None


_LIBC = _libc()


def give_cpu() -> None:
    """Let whatever waits for this thread's CPU run first (a thread's own turn at giving way, between two
    pieces of its work: the timer's signal goes to the main thread).  Called through ctypes.PyDLL, which keeps
    the interpreter: os.sched_yield lets go of it and takes it back, and every such turn cancels another
    thread's pending request for it (that thread starves)."""
    if _SCHED_YIELD is not None:
        _SCHED_YIELD()


_SCHED_YIELD = ctypes.PyDLL(None).sched_yield if _LIBC is not None else None


def _set_handler(action: _SigAction) -> _SigAction | None:
    """Install `action` for SIGALRM; the one it replaces, or None when that failed."""
    old = _SigAction()
    if _LIBC.sigaction(signal.SIGALRM, ctypes.byref(action), ctypes.byref(old)) != 0:
        return None
    return old


def _yield_on_alarm() -> _SigAction:
    """SIGALRM handled by sched_yield(2) itself, in C: the thread the signal interrupts gives way at once,
    wherever it is (in the interpreter or in a C call), and Python never hears of it (a Python handler would
    wait for the interpreter, run in the main thread only, and write every signal to asyncio's wakeup fd).
    sched_yield takes no argument: the signal number passed is ignored."""
    act = _SigAction()
    act.sa_handler = ctypes.cast(_LIBC.sched_yield, ctypes.c_void_p).value
    act.sa_flags = SA_RESTART
    return act


class GiveWay:
    """`with GiveWay(count)` (in the main thread): while `count()` (frames received so far) grows, this process
    hands its CPU back every `period_s`.  Where interval timers or sched_yield are missing, it does nothing."""

    def __init__(self, count: Callable[[], int], period_s: float = GIVE_WAY_S) -> None:
        self.count = count
        self.period_s = period_s
        self.armed = False  # the timer runs
        self.line_busy = False  # frames came in within QUIET_S
        self._watching = False  # watch_loop: armed only while the App's loop works
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._previous = None
        self._usable = hasattr(signal, "setitimer") and _LIBC is not None

    def start(self) -> "GiveWay":
        if self._usable:
            self._previous = _set_handler(_yield_on_alarm())
            self._usable = self._previous is not None
        if self._usable:
            self._thread = threading.Thread(target=self._run, name="give-way", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
            self._thread = None
        if self._previous is not None:
            self._arm(False)
            if self._previous.sa_handler is None:  # SIG_DFL: a signal already sent and delivered later
                self._previous.sa_handler = 1  # would end the process: SIG_IGN instead
            _set_handler(self._previous)
            self._previous = None

    def __enter__(self) -> "GiveWay":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _arm(self, on: bool) -> None:
        with self._lock:  # the loop's thread and the give-way thread
            if on != self.armed:
                signal.setitimer(signal.ITIMER_REAL, self.period_s if on else 0, self.period_s if on else 0)
                self.armed = on

    def watch_loop(self, loop) -> None:
        """The timer only while `loop` (the App's asyncio loop, in this thread) works: waiting in its selector
        it holds no CPU, and a signal would only wake it (2,000 times a second, +5 % of a core)."""
        selector = getattr(loop, "_selector", None)
        select = getattr(selector, "select", None)
        if not self._usable or select is None:
            return

        def waiting(timeout=None):
            if self.armed:
                self._arm(False)
            try:
                return select(timeout)
            finally:
                if self.line_busy and not self._stop.is_set():
                    self._arm(True)

        selector.select = waiting
        self._watching = True

    def _run(self) -> None:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})  # for the threads that draw, not this one
        seen, quiet = self.count(), QUIET_S  # busy only once frames come
        while not self._stop.wait(LOOK_S):
            n = self.count()
            quiet = 0.0 if n != seen else quiet + LOOK_S
            seen = n
            self.line_busy = quiet < QUIET_S
            if not self._watching or not self.line_busy:  # watched: armed by the loop when it wakes
                self._arm(self.line_busy)
        self.line_busy = False
        self._arm(False)
