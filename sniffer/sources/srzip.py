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
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass

from sniffer.events import CaptureError
from sniffer.formats.reading import open_regular

BLOCK = 1 << 20  # bytes of samples handed out at a time

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
        with zipfile.ZipFile(os.fspath(path)) as z:
            names = set(z.namelist())
    except (CaptureError, OSError, zipfile.BadZipFile, ValueError):
        return False
    return "metadata" in names and "version" in names


def _member_order(name: str, prefix: str) -> int | None:
    """logic-1-12 -> 12 (the sample order), None for a member of another prefix."""
    if name == prefix:
        return 0
    head, _, n = name.rpartition("-")
    return int(n) if head == prefix and n.isdigit() else None


def read_meta(path: str | os.PathLike[str]) -> SrMeta:
    """The file's SrMeta; CaptureError (one line) for a file that is not a readable sigrok session."""
    p = os.fspath(path)
    open_regular(p).close()  # a directory, FIFO or missing file: the same one line as every reader
    try:
        with zipfile.ZipFile(p) as z:
            text = z.read("metadata").decode("utf-8", "replace")
            infos = z.infolist()
    except KeyError:
        raise CaptureError(f"{p}: not a sigrok session file (no metadata in the zip)") from None
    except (zipfile.BadZipFile, OSError, ValueError) as e:
        raise CaptureError(f"{p}: not a readable sigrok session file ({e})") from None
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
    try:
        unitsize = int(dev.get("unitsize", "1"))
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
    total = sum(size for _, _, size in members)
    if not members or total < unitsize:
        raise CaptureError(f"{p}: no logic samples in it")
    return SrMeta(p, rate, dict(sorted(channels.items(), key=lambda kv: kv[1])), unitsize,
                  tuple(name for _, name, _ in members), total // unitsize)


def logic_blocks(meta: SrMeta, block: int = BLOCK) -> Iterator[bytes]:
    """The samples in pieces of whole samples (at most about `block` bytes): memory stays flat."""
    unit = meta.unitsize
    block -= block % unit
    pending = b""
    try:
        with zipfile.ZipFile(meta.path) as z:
            for name in meta.files:
                with z.open(name) as fh:
                    while True:
                        data = fh.read(block)
                        if not data:
                            break
                        if pending:
                            data = pending + data
                        cut = len(data) - len(data) % unit
                        pending = data[cut:]
                        if cut:
                            yield data[:cut]
    except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError) as e:
        raise CaptureError(f"{meta.path}: its samples cannot be read ({e})") from None
