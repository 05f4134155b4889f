"""`sniffer diff A B`: what changed between two captures (exit 0 nothing, 1 something, 2 error)."""

from __future__ import annotations

import sys

from ..semdiff import diff
from ..settings import CaptureSpec


def cmd_diff(spec: CaptureSpec, args) -> int:
    import orjson

    report = diff(args.a, args.b, spec.with_(input=None))
    if args.format == "json":
        sys.stdout.write(orjson.dumps(report.to_dict(), option=orjson.OPT_INDENT_2).decode() + "\n")
    else:
        sys.stdout.write(report.to_text())
    return 0 if report.same else 1
