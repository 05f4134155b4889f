"""The viewers' stream: how a running capture talks to `sniffer attach` and `sniffer serve`.

The capture (sinks/publish.py) listens on a Unix socket (mode 0600) or, if
asked, a TCP port; viewers (attach.py) connect and read newline-delimited JSON:

    {"sniffer": "header", ...}    first: capture info, MCAP path, frames not sent
    {"index": 0, "t": ..., ...}   one frame record (sniffer.records) per frame
    {"sniffer": "status", ...}    about once a second: bytes in, frames, noise, MCAP size
    {"sniffer": "skipped", ...}   this viewer fell behind: that many frames were left out
    {"sniffer": "end", ...}       the capture ended (last line)

The writer and the reader share this module; neither imports the other.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from .records import dumps
from .sources import CaptureError

STREAM_VERSION = 1
CONTROL_PREFIX = b'{"sniffer"'  # control lines start so; frame records start with {"index"


class PublishError(CaptureError):
    """A viewer address that cannot be used: one line for the user, exit code 2."""


@dataclass(frozen=True, slots=True)
class Address:
    """Where a capture publishes: a Unix socket path, or `tcp:[HOST:]PORT` (host default 127.0.0.1)."""

    path: str | None = None
    host: str = "127.0.0.1"
    port: int = 0

    def __str__(self) -> str:
        return self.path if self.path is not None else f"tcp:{self.host}:{self.port}"


def parse_address(spec: str) -> Address:
    """`PATH` (a Unix socket) or `tcp:[HOST:]PORT`; PublishError (one line) for anything else."""
    shown = spec if len(spec) <= 200 else spec[:197] + "..."
    if not spec or "\0" in spec:
        raise PublishError(f"{shown!r}: not a socket path")
    if not spec.startswith("tcp:"):
        if len(os.fsencode(spec)) > 107:  # sun_path holds 108 bytes with its NUL
            raise PublishError(f"{shown}: a Unix socket path is at most 107 bytes long")
        return Address(path=spec)
    host, _, port = spec[4:].rpartition(":")
    try:
        n = int(port)
    except ValueError:
        raise PublishError(f"{shown}: a TCP address is tcp:PORT or tcp:HOST:PORT") from None
    if not 0 <= n <= 65535:
        raise PublishError(f"{shown}: TCP port {n} is outside 0..65535")
    return Address(host=host.strip("[]") or "127.0.0.1", port=n)


def control(kind: str, **fields) -> bytes:
    return dumps({"sniffer": kind, **fields}) + b"\n"
