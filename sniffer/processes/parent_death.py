"""A child that ends with its parent: Linux's PR_SET_PDEATHSIG, and a watcher for worker processes.

`serve` runs the capture and one viewer per browser as processes of its own.  If `serve` itself dies
(SIGKILL, a crash), nothing would stop them: the capture would go on writing, each viewer spin on a
closed pipe.  `die_with_parent(sig)` asks the kernel to send `sig` when the parent ends (SIGINT to
the capture, which then closes its MCAP as on Ctrl-C; SIGKILL to a viewer, which holds no file).

External programs (sigrok-cli) get the same through `external_ends_with_parent()` as their preexec_fn.

The worker processes of `--jobs` (sniffer.parallel: a replay's parts, an ingest's captures) and of
`detect` (one per port) call `worker_ends_with_parent(*worker_args())` first: a parent killed outright
(SIGKILL, the OOM killer) leaves no worker decoding on for nobody.
"""

from __future__ import annotations

import os
import signal
import threading
import time

from sniffer.orphans import die_with_parent, external_ends_with_parent  # noqa: F401 - the processes' too

WATCH_S = 0.5  # how often a worker looks whether its parent is still there


def worker_ends_with_parent(parent_pid: int, from_main_thread: bool) -> None:
    """In a worker process (an initializer, a Process target's first line): end it, by SIGKILL, when the process
    `parent_pid` that started it ends, even killed outright.

    A worker holds nothing that needs closing (its parent takes its results in; an ingest's staging folder is
    tidied by the next run, its lock freed with the process), and SIGKILL cannot be caught by a handler the
    worker inherited from its parent's fork (a SIGTERM handler that only sets the parent's stop event).
    The kernel's PR_SET_PDEATHSIG fires when the *thread* that started the worker ends, so it is asked for
    only when the parent's main thread started it (`from_main_thread`); a watcher thread that sees the
    parent's pid change (the worker given to init or a subreaper) covers the rest, and other systems.
    """
    if from_main_thread:
        die_with_parent(signal.SIGKILL)
    if os.getppid() != parent_pid:  # the parent ended before we looked
        os.kill(os.getpid(), signal.SIGKILL)
    threading.Thread(target=_watch, args=(parent_pid,), name="parent-watch", daemon=True).start()


def _watch(parent_pid: int) -> None:
    while True:
        time.sleep(WATCH_S)
        if os.getppid() != parent_pid:
            os.kill(os.getpid(), signal.SIGKILL)


def worker_args() -> tuple[int, bool]:
    """What a parent gives `worker_ends_with_parent` (its pid, whether its main thread is starting the worker)."""
    return os.getpid(), threading.current_thread() is threading.main_thread()
