"""The viewers' stream: how a running capture talks to `sniffer attach` and `sniffer serve`.

The capture (processes/publish_sink.py) listens on a Unix socket (mode 0600) or, if
asked, a TCP port; viewers (attach.py) connect and read newline-delimited JSON:

    {"sniffer": "header", ...}    first: capture info, MCAP path, frames not sent
    {"index": 0, "t": ..., ...}   one frame record (sniffer.formats.records) per frame
    {"sniffer": "status", ...}    about once a second: bytes in, frames, noise, MCAP size
    {"sniffer": "skipped", ...}   this viewer fell behind: that many frames were left out
    {"sniffer": "reads", "r": [...]}  reads as the port delivered them (the TUI's byte view), see below
    {"sniffer": "end", ...}       the capture ended (last line)

Reads (sniffer.analysis.reads.Read) travel in batches, a read once every byte of it is
in a settled frame, each read a compact array:

    [t, offset, "hex", cont, [pos, index, pos, index, ...]]   + [last, "channel"] when not per read / ""
                                                              + ["link"] in a capture of several links
                                                              + [unseen] after the reader stalled

`t`: ns since the capture's t0 (per read: when it returned; per byte: its
first byte); `offset`: bytes of the capture before it; `cont`: 1 if its first
byte continues a frame begun in an earlier read; then (position, frame index)
of the frame byte 0 went to and of each frame that begins in it; `last`: ns
since t0 of its last byte (per-byte sources only); `unseen`: ns the port went
unseen before the read, when the live reader stalled (Chunk.unseen_ns; the
elements before it are then all there).  A late viewer gets the
last RING_READS reads after the frame backlog; a viewer that falls behind
loses reads before frames.  Viewers that do not know the line skip it (as any
control line of an unknown kind), so it needed no new STREAM_VERSION.

The writer and the reader share this module; neither imports the other.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from sniffer.analysis.reads import Read
from sniffer.formats.records import dumps
from sniffer.events import CaptureError

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


def read_item(r: Read, t0_ns: int) -> bytes:
    """One read as the array of a reads line (see the module doc)."""
    item = [r.t_ns - t0_ns, r.offset, r.data.hex(), int(r.cont), [x for m in r.marks for x in m]]
    if r.last_ns is not None or r.channel or r.link or r.unseen_ns is not None:
        item += [None if r.last_ns is None else r.last_ns - t0_ns, r.channel]
    if r.link or r.unseen_ns is not None:
        item.append(r.link)
    if r.unseen_ns is not None:
        item.append(r.unseen_ns)
    return dumps(item)


def reads_line(items: list[bytes]) -> bytes:
    """A reads control line of reads already encoded by read_item."""
    return b'{"sniffer":"reads","r":[' + b",".join(items) + b"]}\n"


def parse_reads(msg: dict, t0_ns: int) -> list[Read]:
    """The reads of a reads line (ValueError, KeyError, TypeError: a damaged one)."""
    out = []
    for item in msg.get("r") or ():
        t, off, data, cont, flat = item[:5]
        last, channel, link = (item[5:8] + [None, "", ""][len(item[5:8]):]) if len(item) > 5 else (None, "", "")
        unseen = item[8] if len(item) > 8 else None
        marks = tuple((int(flat[k]), int(flat[k + 1])) for k in range(0, len(flat) - 1, 2))
        out.append(Read(t0_ns + int(t), int(off), bytes.fromhex(data), marks, bool(cont),
                        None if last is None else t0_ns + int(last), str(channel or ""), str(link or ""),
                        None if unseen is None else int(unseen)))
    return out
