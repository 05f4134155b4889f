"""A live capture's current view through its socket (`--publish`, `sniffer serve`), as `sniffer attach` sees
it: the capture's description and status, and the newest frames of its backlog and of a short listen.

A viewer only reads: it cannot stop the capture nor delay its reads, and leaves after `seconds`.
"""

from __future__ import annotations

import time
from collections import Counter, deque

from sniffer.assistant.bounds import ANSWER_BYTES, fit, scrub

MAX_SECONDS = 10.0


def view(address: str, seconds: float = 1.0, limit: int = 20) -> dict:
    """What the capture at `address` shows now: its line, status, per-unit counts and errors of the frames
    heard in `seconds` (its backlog first), and the last `limit` of those frames."""
    from sniffer.formats.records import loads
    from sniffer.processes.attach import Attachment
    from sniffer.processes.stream import CONTROL_PREFIX

    att = Attachment(address, timeout_s=min(5.0, max(seconds, 1.0)))
    last = deque(maxlen=limit)
    heard = 0
    units: dict[str, Counter] = {}
    end = time.monotonic() + seconds
    try:
        for lines in _until(att, end):
            for line in lines:
                if line.startswith(CONTROL_PREFIX):
                    att.control(line)
                elif line:
                    rec = loads(line)
                    heard += 1
                    last.append(rec)
                    c = units.setdefault(str(rec.get("unit")), Counter())
                    c[rec.get("role") or "unknown"] += 1
                    c["errors"] += any(a.get("severity") == "error" for a in rec.get("annotations") or ())
    finally:
        att.close()
    status = {k: v for k, v in att.status.items() if k != "sniffer"}
    frames, cut = fit(scrub(list(last)), ANSWER_BYTES - 4_000)
    return {"socket": address, "capture": scrub(att.describe()), "capture_file": scrub(att.capture_path),
            "ended": att.ended is not None, "status": scrub(status), "frames_heard": heard,
            "units": {u: dict(c) for u, c in sorted(units.items())}, "last_frames": frames, "cut_by_size": cut}


def _until(att, end: float):
    """The attachment's batches until `end` (monotonic) or the capture's end (a quiet line included: the
    timer stops the wait)."""
    import threading

    stop = threading.Event()
    timer = threading.Timer(max(0.0, end - time.monotonic()), stop.set)
    timer.start()
    try:
        for lines in att.batches(stop, poll_s=0.05):
            yield lines
            if att.ended is not None:
                return
    finally:
        timer.cancel()
