"""Children that end with their parent: Linux's PR_SET_PDEATHSIG (sniffer.processes.parent_death builds on it).

A module of its own, below every package, so that a source (sniffer.sources.sigrok_cli) can ask it for the
external programs it starts without depending on sniffer.processes.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import threading

PR_SET_PDEATHSIG = 1


def die_with_parent(sig: int) -> bool:
    """Have the kernel send `sig` to this process when its parent ends; False where it cannot (not Linux)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0) != 0:
            return False
    except OSError:
        return False
    if os.getppid() == 1:  # the parent ended before we asked
        os.kill(os.getpid(), sig)
    return True


def external_ends_with_parent(sig: int = signal.SIGKILL):
    """A `preexec_fn` for subprocess.Popen of an external program (sigrok-cli): the kernel sends it `sig` when
    this process ends, killed outright included (the setting survives exec).  Without it a killed `replay
    FILE.sr` or `live sigrok:DEVICE` left sigrok-cli decoding, or an analyzer acquiring, for nobody.

    The kernel sends it when the *thread* that started the child ends, so it is asked for only from the main
    thread (a TUI worker thread ends before the capture does); elsewhere None: the child then ends on the
    broken pipe of its next write once its reader is gone."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return lambda: die_with_parent(sig)
