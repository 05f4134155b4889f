"""The sigrok session file (.sr): a zip of `version`, `metadata` and the logic samples `logic-1-1`, `logic-1-2`...

    meta = read_meta("line.sr")      # SrMeta: sample rate, channel names by bit, unit size, sample count
    for block in logic_blocks(meta): # the raw samples, `unitsize` bytes each, in pieces (flat memory)
        ...

`metadata` is an INI file; its `[device 1]` section names the capture file
prefix (`capturefile=logic-1`), the sample rate (`samplerate=1 MHz`), the unit
size in bytes and one `probeN=NAME` line per logic channel: channel NAME is bit
N-1 of every sample (little-endian).  Only the logic channels of the first
device are read (what libsigrok's srzip output writes); analog channels are
ignored.  Readers of sample rates typed by people (`--samplerate 1M`) use
`parse_rate` too.
"""

from __future__ import annotations

import configparser
import os
import re
import stat
from collections.abc import Iterator
from dataclasses import dataclass

from sniffer.events import CaptureError
from sniffer.inputs import Archive, open_regular
from sniffer.inputs.archive import size_text

BLOCK = 1 << 20  # bytes of samples handed out at a time
WHAT = "a sigrok session file"
MAX_METADATA = 1 << 20  # an INI of a few lines
# 1 GiB of samples: 45 s at 24 MHz, 18 min at 1 MHz; sigrok-cli takes minutes to decode more, and idle samples
# deflate 1000:1, so a 3 MB file can hold 3 GB of them
MAX_SAMPLE_BYTES = 1 << 30

_RATE = re.compile(r"\s*([0-9]+(?:\.[0-9]+)?)\s*([kKmMgG]?)(?:[hH][zZ])?\s*")
_SCALE = {"": 1, "k": 1_000, "m": 1_000_000, "g": 1_000_000_000}


def parse_rate(text: str) -> int:
    """'1 MHz', '4MHz', '1M', '500k', '24000000' -> Hz; ValueError for anything else."""
    m = _RATE.fullmatch(text or "")
    if m is None:
        raise ValueError(f"not a sample rate: {text[:40]!r} (e.g. 1M, 24MHz, 500k)")
    whole, _, frac = m.group(1).partition(".")
    scale = _SCALE[m.group(2).lower()]
    digits = int(whole + frac)
    hz, rem = divmod(digits * scale, 10 ** len(frac))
    if rem or hz <= 0:
        raise ValueError(f"not a whole number of Hz: {text[:40]!r}")
    return hz


def rate_text(hz: int) -> str:
    """1000000 -> '1 MHz' (as sigrok writes it; exact: 1500 -> '1500 Hz')."""
    for scale, unit in ((1_000_000_000, "GHz"), (1_000_000, "MHz"), (1_000, "kHz")):
        if hz % scale == 0:
            return f"{hz // scale} {unit}"
    return f"{hz} Hz"


@dataclass(frozen=True)
class SrMeta:
    path: str
    samplerate: int
    channels: dict[str, int]  # logic channel name -> bit index in a sample
    unitsize: int
    files: tuple[str, ...]  # the logic members, in order
    samples: int  # samples in the file (the logic members' size / unitsize)

    def bit(self, name: str) -> int:
        """The bit of channel `name` (a name as the file spells it, or its number); CaptureError if none."""
        if name in self.channels:
            return self.channels[name]
        raise CaptureError(f"{self.path}: no logic channel {name!r} (channels: {', '.join(self.channels)})")


def sniff(path: str | os.PathLike[str]) -> bool:
    """Is this a sigrok session file (a zip holding `metadata` and `version`)?  Only a regular file is opened
    (`detect /dev/ttyUSB0` asks too: a serial port is never opened here)."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return False
        with open_regular(path) as fh:
            if fh.read(4) != b"PK\x03\x04":
                return False
        with Archive(os.fspath(path), WHAT) as z:
            names = set(z.names())
    except (CaptureError, OSError):
        return False
    return "metadata" in names and "version" in names


def _member_order(name: str, prefix: str) -> int | None:
    """logic-1-12 -> 12 (the sample order), None for a member of another prefix."""
    if name == prefix:
        return 0
    head, _, n = name.rpartition("-")
    return int(n) if head == prefix and n.isdigit() and int(n) > 0 else None  # sigrok counts from 1


def read_meta(path: str | os.PathLike[str]) -> SrMeta:
    """The file's SrMeta; CaptureError (one line) for a file that is not a readable sigrok session, or one
    sigrok-cli would stop reading early (a member missing from the numbering, no unit size): decoded, it
    would give the frames before the gap and not a word about the rest."""
    p = os.fspath(path)
    with Archive(p, WHAT) as z:
        z.require(["metadata"])
        text = z.read("metadata", MAX_METADATA).decode("utf-8", "replace")
        infos = list(z.infos.values())
        ini = configparser.ConfigParser(interpolation=None, strict=False)
        try:
            ini.read_string(text)
        except configparser.Error as e:
            raise CaptureError(f"{p}: its metadata is not readable ({str(e).splitlines()[0]})") from None
        if not ini.has_section("device 1"):
            raise CaptureError(f"{p}: its metadata has no [device 1] section")
        dev = ini["device 1"]
        try:
            rate = parse_rate(dev.get("samplerate", ""))
        except ValueError:
            raise CaptureError(f"{p}: its metadata gives no sample rate ({dev.get('samplerate')!r})") from None
        if "unitsize" not in dev:
            raise CaptureError(f"{p}: its metadata gives no unitsize (bytes a sample): sigrok-cli reads no "
                               "samples without it")
        try:
            unitsize = int(dev.get("unitsize"))
        except ValueError:
            unitsize = 0
        if not 1 <= unitsize <= 8:
            raise CaptureError(f"{p}: unit size {dev.get('unitsize')!r} is not 1..8 bytes")
        channels: dict[str, int] = {}
        for key, name in dev.items():
            if key.startswith("probe") and key[5:].isdigit():
                bit = int(key[5:]) - 1
                if 0 <= bit < 8 * unitsize:
                    channels[name.strip()] = bit
        if not channels:
            raise CaptureError(f"{p}: no logic channels in its metadata")
        prefix = dev.get("capturefile", "logic-1").strip()
        members = sorted((order, i.filename, i.file_size) for i in infos
                         if (order := _member_order(i.filename, prefix)) is not None)
        _check_numbering(p, prefix, [order for order, _, _ in members])
        total = 0
        for _, name, size in members:  # each member's method, flags, size and ratio, before sigrok-cli reads it
            z.check(name, MAX_SAMPLE_BYTES)
            total += size
    if not members or total < unitsize:
        raise CaptureError(f"{p}: no logic samples in it")
    if total > MAX_SAMPLE_BYTES:
        raise CaptureError(f"{p}: {size_text(total)} of samples inflated, over the {size_text(MAX_SAMPLE_BYTES)} "
                           "this reader takes (record shorter captures: each is decoded on its own)")
    return SrMeta(p, rate, dict(sorted(channels.items(), key=lambda kv: kv[1])), unitsize,
                  tuple(name for _, name, _ in members), total // unitsize)


def _check_numbering(path: str, prefix: str, orders: list[int]) -> None:
    """The logic members are `prefix` alone or `prefix-1` ... `prefix-N` without a gap: sigrok-cli stops at the
    first member missing from the numbering, and everything after it would be lost without a word."""
    if orders == [0]:
        return
    if 0 in orders:
        raise CaptureError(f"{path}: both {prefix} and {prefix}-N members: not a session sigrok writes")
    want = list(range(1, len(orders) + 1))
    if orders != want:
        gap = next((n for n, o in zip(want, orders) if n != o), len(orders) + 1)
        raise CaptureError(f"{path}: logic member {prefix}-{gap} is missing (members {_runs(orders)}): sigrok-cli "
                           f"would stop there and lose what follows")


def _runs(orders: list[int]) -> str:
    out, start = [], None
    for i, o in enumerate(orders):
        if start is None:
            start = o
        if i + 1 == len(orders) or orders[i + 1] != o + 1:
            out.append(f"{start}" if start == o else f"{start}-{o}")
            start = None
    return ", ".join(out)


def logic_blocks(meta: SrMeta, block: int = BLOCK) -> Iterator[bytes]:
    """The samples in pieces of whole samples (at most about `block` bytes): memory stays flat."""
    unit = meta.unitsize
    block -= block % unit
    pending = b""
    with Archive(meta.path, WHAT) as z:
        for name in meta.files:
            for data in z.stream(name, MAX_SAMPLE_BYTES, block):
                if pending:
                    data = pending + data
                cut = len(data) - len(data) % unit
                pending = data[cut:]
                if cut:
                    yield data[:cut]
