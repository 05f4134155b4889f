"""Open any capture file for replay: MCAP, byte CSV or Saleae CSV."""

from __future__ import annotations

import os

from . import CaptureError

FORMATS = ("auto", "mcap", "csv", "saleae", "pcap")


def open_replay(path: str, fmt: str = "auto"):
    """(CaptureInfo, events iterator) or CaptureError with one clear line."""
    from . import bytecsv, mcapsrc, pcapsrc, saleae

    if not os.path.exists(path):
        raise CaptureError(f"{path}: no such file")
    if os.path.isdir(path):
        raise CaptureError(f"{path}: is a directory, not a capture file")
    if fmt == "auto":
        if mcapsrc.sniff(path):
            fmt = "mcap"
        elif bytecsv.sniff(path):
            fmt = "csv"
        elif pcapsrc.sniff(path):
            fmt = "pcap"
        elif saleae.sniff(path):
            fmt = "saleae"
        else:
            raise CaptureError(
                f"{path}: unknown capture format (expected MCAP from this tool, a byte CSV "
                "t_s,channel,byte_hex,flags, a Saleae async-serial CSV export, or pcap/pcapng)"
            )
    if fmt == "mcap":
        return mcapsrc.open_mcap(path)
    if fmt == "csv":
        return bytecsv.open_byte_csv(path)
    if fmt == "saleae":
        return saleae.open_saleae_csv(path)
    if fmt == "pcap":
        return pcapsrc.open_pcap(path)
    raise CaptureError(f"unknown input format {fmt!r} (one of {', '.join(FORMATS)})")
