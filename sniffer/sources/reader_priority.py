"""A live capture's reader thread asks for a real-time priority, where the system grants one.

A read that comes late holds a request and its answer together, and the answer loses its latency
(serial_live.py).  The reader sleeps in select() and is woken when bytes arrive; on Linux 6.x a normal
thread woken onto a CPU where another normal thread is running waits until that thread enters the
kernel or the next tick (up to 4 ms at HZ=250), whatever their nice levels.  A SCHED_FIFO thread
preempts it at once.  Traced with a TUI open, most long waits were the capture's reader behind the
viewer; at SCHED_FIFO 1 fewer answers are glued, and headless capture is unchanged
(benchmarks/bench_capture_timing.py; the traces are in benchmarks/HISTORY.md).

The lowest real-time priority (1) is enough: it only has to come before normal work.  The reader's
work per wake is small (a read, a timestamp, a queue push); Linux's real-time throttling still keeps
5 % of every second for normal work should it ever spin.  Granted to root, to a process with
CAP_SYS_NICE, or where RLIMIT_RTPRIO allows it (`ulimit -r`, /etc/security/limits.conf); elsewhere the
reader stays a normal thread and the capture's metadata says why (`extra.reader`).  SNIFFER_REALTIME=off
in the environment declines it (root included, whom `ulimit -r 0` does not bind); the capture processes the
TUI and `serve` start inherit it.
"""

from __future__ import annotations

import os

READER_RT_PRIORITY = 1  # SCHED_FIFO's lowest: ahead of every normal thread, behind the kernel's own
DECLINE_ENV = "SNIFFER_REALTIME"  # "off" (or 0, no, false): the reader stays a normal thread


def raise_reader(tid: int) -> dict:
    """Thread `tid` (a reader's native id) to SCHED_FIFO at READER_RT_PRIORITY; what it got, for the
    capture's metadata."""
    if os.environ.get(DECLINE_ENV, "").strip().lower() in ("off", "0", "no", "false"):
        return {"policy": "normal", "why": f"declined ({DECLINE_ENV}=off)"}
    if not hasattr(os, "sched_setscheduler"):  # not Linux
        return {"policy": "normal", "why": "no sched_setscheduler on this system"}
    try:
        os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(READER_RT_PRIORITY))
    except OSError as e:
        return {"policy": "normal", "why": e.strerror or str(e)}
    return {"policy": "SCHED_FIFO", "priority": READER_RT_PRIORITY}
