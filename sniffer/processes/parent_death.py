"""A child that ends with its parent: Linux's PR_SET_PDEATHSIG, for the processes `sniffer serve` starts.

`serve` runs the capture and one viewer per browser as processes of its own.  If `serve` itself dies
(SIGKILL, a crash), nothing would stop them: the capture would go on writing, each viewer spin on a
closed pipe.  `die_with_parent(sig)` asks the kernel to send `sig` when the parent ends (SIGINT to
the capture, which then closes its MCAP as on Ctrl-C; SIGKILL to a viewer, which holds no file).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

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
