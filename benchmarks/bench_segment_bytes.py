"""What a live capture's MCAP costs on disk against the line's raw bytes, and what takes the bytes.

    .venv/bin/python benchmarks/bench_segment_bytes.py [--scenario default] [--seconds 100] [--levels 3,9,19]
                                                       [--full] [--seal 30]

A simulated line (read by a USB adapter) goes through a capture session into McapSink as a live
capture's segment writes it (compact: /raw batched, no /frames; --full: a message per event and per
frame, as `live --out` and exports write): the sink's clock is the capture's own, so the open chunk
is written every second of capture (what a SIGKILL may lose) and sealed every --seal seconds.
Printed: the line's bytes a second, the file's, their ratio (the aim: at most 5x), the chunks, the
message indexes' bytes, each topic's uncompressed bytes, and the chunks compressed again at other
zstd levels, alone and grouped by 3 and 10.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import collections
import os
import struct
import sys
import tempfile

import zstandard


def live_capture(path: str, scenario: str, seconds: float, compact: bool = True, seal: float = 30.0) -> int:
    """Write the capture as a live one; the line's raw bytes."""
    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.events import CaptureInfo
    from sniffer.formats.mcap.sink import McapSink
    from sniffer.simulator import get_scenario, simulate, usb_chunks

    sc = get_scenario(scenario)
    chunks = list(usb_chunks(simulate(sc, sc.line, seconds, 1)))
    now = [0]

    class Events:
        def __iter__(self):
            for c in chunks:
                now[0] = c.t_ns  # the sink's clock: a flush every second of capture
                yield c

    info = CaptureInfo(baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits, time_source="read")
    Session(CaptureSpec(), EventSource(info, Events()), [McapSink(path, clock=lambda: now[0], compact=compact,
                                                                     seal_interval_s=seal)]).run()
    return sum(len(c.data) for c in chunks)


def chunk_bodies(path: str) -> list[bytes]:
    """Every chunk's records, uncompressed."""
    from mcap.reader import make_reader

    out = []
    with open(path, "rb") as f:
        for ci in make_reader(f).get_summary().chunk_indexes:
            f.seek(ci.chunk_start_offset + 9)
            body = f.read(ci.chunk_length - 9)
            usize = struct.unpack_from("<Q", body, 16)[0]
            n = struct.unpack_from("<I", body, 28)[0]
            comp = body[32:32 + n].decode()
            size = struct.unpack_from("<Q", body, 32 + n)[0]
            data = body[40 + n:40 + n + size]
            out.append(zstandard.ZstdDecompressor().decompress(data, max_output_size=usize) if comp else data)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--seconds", type=float, default=100.0)
    ap.add_argument("--levels", default="3,9,19")
    ap.add_argument("--full", action="store_true", help="a message per event and per frame (not a segment's)")
    ap.add_argument("--seal", type=float, default=30.0, help="seconds the open chunk stays open")
    args = ap.parse_args()
    from mcap.reader import make_reader

    path = os.path.join(tempfile.mkdtemp(prefix="bench_segment_bytes_"), "live.mcap")
    raw = live_capture(path, args.scenario, args.seconds, not args.full, args.seal)
    size = os.path.getsize(path)
    s = args.seconds
    print(f"{args.scenario}, {s:.0f} s: the line {raw / s:,.0f} B/s, the file {size / s:,.0f} B/s: "
          f"{size / raw:.1f}x the line (aim: at most 5x)")
    topics, counts = collections.Counter(), collections.Counter()
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, ch, m in reader.iter_messages():
            t = "/values/*" if ch.topic.startswith("/values") else ch.topic
            topics[t] += len(m.data)
            counts[t] += 1
        summary = reader.get_summary()
    cis = summary.chunk_indexes
    packed = sum(c.compressed_size for c in cis)
    print(f"{len(cis)} chunks: {packed:,} B compressed of {sum(c.uncompressed_size for c in cis):,}; "
          f"message indexes {sum(c.message_index_length for c in cis):,} B; the rest (header, schemas, channels, "
          f"attachments, summary) {size - packed - sum(c.message_index_length for c in cis):,} B")
    for t, n in topics.most_common():
        print(f"  {t:12s} {n:>10,} B uncompressed in {counts[t]:,} messages ({n / counts[t]:.0f} B each)")
    bodies = chunk_bodies(path)
    for level in (int(x) for x in args.levels.split(",")):
        z = zstandard.ZstdCompressor(level=level)
        row = [f"zstd {level:2d}:"]
        for group in (1, 3, 10):
            n = sum(len(z.compress(b"".join(bodies[i:i + group]))) for i in range(0, len(bodies), group))
            row.append(f"{group:2d} chunks as one {n:>9,} B ({n / raw:.1f}x)")
        print("  ".join(row))


if __name__ == "__main__":
    sys.exit(main())
