"""What a capture wrote, in words: the default file name, the files and their sizes, the closing line."""

from __future__ import annotations

import os
import time

from sniffer.sinks.base import Sink


def default_capture_name() -> str:
    return time.strftime("sniffer-%Y%m%d-%H%M%S.mcap")


def written(session) -> str:
    """'; MCAP cab3.mcap (123456 bytes)' for the files a session wrote, or ''."""
    parts = []
    for o in session.outputs:
        if o.state != "committed":
            continue
        try:
            size = os.path.getsize(o.path)
        except OSError:
            continue
        kind = os.path.splitext(o.path)[1].lstrip(".").upper() or "file"
        parts.append(f"{kind} {o.path} ({size} bytes)")
    parts += [s.written_text for s in session.sinks if isinstance(s, Sink) and s.written_text]
    return "; " + ", ".join(parts) if parts else ""


def summary_line(session) -> str:
    return (f"sniffer: {session.frames_out} frames, {session.bytes_in} bytes, {session.noise_bytes} noise bytes"
            f"{written(session)}")
