"""`sniffer check CAPTURE --golden FILE`: exit 0 same, 1 different (a unified diff on stdout), 2 error."""

from __future__ import annotations

import sys

from ..golden import Tolerances, check
from ..settings import CaptureSpec


def cmd_check(spec: CaptureSpec, args) -> int:
    from ..settings import finite

    tol = Tolerances(finite(args.time_tol_ms, "--time-tol-ms", upper=1e9),
                     finite(args.latency_tol_ms, "--latency-tol-ms", upper=1e9))
    rc, text = check(spec.input, args.golden, spec=spec, update=args.update_golden, tolerances=tol)
    (sys.stdout if rc == 1 else sys.stderr).write(text)
    return rc
