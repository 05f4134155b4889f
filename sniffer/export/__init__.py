"""Export a decoded capture: csv, parquet, pcap/pcapng (Wireshark Modbus/RTU), mcap (re-decoded).

    export(capture, fmt, out, options)  ->  number of frames written

Each format is a pipeline sink (start/raw/frame/close), so a live capture or
a replay can write it too.  JSONL is `sniffer replay --format jsonl`.
"""

from __future__ import annotations

import os

FORMATS = ("csv", "parquet", "pcap", "pcapng", "mcap")


def make_sink(fmt: str, out: str | os.PathLike[str]):
    if fmt == "csv":
        from ..sinks.tables import CsvSink

        return CsvSink(out)
    if fmt == "parquet":
        from ..sinks.tables import ParquetSink

        return ParquetSink(out)
    if fmt in ("pcap", "pcapng"):
        from ..sinks.pcap import PcapSink

        return PcapSink(out, ng=True if fmt == "pcapng" else None)  # pcap: pcapng if OUT ends .pcapng
    if fmt == "mcap":
        from ..sinks.mcap import McapSink

        return McapSink(out)
    raise ValueError(f"unknown export format {fmt!r} (one of {', '.join(FORMATS)})")


def export(capture, fmt: str, out, options=None, progress: bool = False) -> int:
    """Decode `capture` (sniffer.regress.DecodeOptions) and write it as `fmt` to `out`.

    csv writes OUT (frames) and OUT's stem + '.points.csv'; parquet writes
    OUT (frames) and stem + '.points.parquet'.  A Ctrl-C stops the replay and
    still closes the output, so what was written is a valid file.
    """
    from ..regress import decode_capture

    sink = make_sink(fmt, out)
    on_event = None
    bar = None
    if progress:
        from ..progress import ReplayProgress

        bar = ReplayProgress(capture)
        on_event = bar.update
    try:
        _info, frames = decode_capture(capture, options, sinks=[sink], on_event=on_event)
    finally:
        if bar is not None:
            bar.close()
    return len(frames)
