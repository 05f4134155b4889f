"""Zip archives (a sigrok .sr session is one), opened by one helper that bounds what they may inflate to.

    with Archive(path, "a sigrok session file") as z:
        z.require(["metadata", "version"])          # every member the reader needs, or one line
        text = z.read("metadata", 1 << 20)          # the whole member, at most that many bytes inflated
        for piece in z.stream("logic-1-1", cap):    # a big member in pieces

Refused, each in one line (InputError) before a byte of the member is inflated: an encrypted member, a
compression method other than stored or deflate (the only two sigrok and most writers use), a member
whose declared size is over its cap, a member claiming more than MAX_RATIO times its compressed size
(deflate cannot exceed ~1032:1: a header that says more is forged).  The inflated bytes are bounded by
the declared size (zipfile stops there and checks the CRC), so a header that lies is caught too.
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Iterator, Sequence

from sniffer.inputs.errors import InputError
from sniffer.inputs.files import open_regular

MAX_RATIO = 1100  # inflated : compressed, just above what deflate can reach
METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate"}
_READ_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, EOFError, OSError, ValueError,
                RuntimeError, NotImplementedError)


def size_text(n: int) -> str:
    """1610612736 -> '1.5 GiB' (what a cap or a member's size says in an error)."""
    for unit, shift in (("GiB", 30), ("MiB", 20), ("kiB", 10)):
        if n >= 1 << shift:
            return f"{n / (1 << shift):.1f} {unit}"
    return f"{n} bytes"


class Archive:
    def __init__(self, path: str, what: str, max_ratio: int = MAX_RATIO) -> None:
        self.path = path
        self.what = what
        self.max_ratio = max_ratio
        self._fh = open_regular(path, what)
        try:
            self.zip = zipfile.ZipFile(self._fh)
            self.infos = {i.filename: i for i in self.zip.infolist()}
        except _READ_ERRORS as e:
            self._fh.close()
            raise InputError(f"{path}: not {what} (not a readable zip: {str(e)[:120]})") from None

    def __enter__(self) -> Archive:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.zip.close()
        self._fh.close()

    def names(self) -> list[str]:
        return list(self.infos)

    def require(self, names: Sequence[str]) -> None:
        missing = [n for n in names if n not in self.infos]
        if missing:
            raise InputError(f"{self.path}: not {self.what} (no {', '.join(missing)} in the zip)")

    def check(self, name: str, cap: int) -> zipfile.ZipInfo:
        """The member's entry once its flags, method, size and ratio pass; InputError (one line) if not."""
        info = self.infos.get(name)
        if info is None:
            raise InputError(f"{self.path}: no member {name!r} in {self.what}")
        if info.flag_bits & 0x1:
            raise InputError(f"{self.path}: member {name!r} is encrypted: not {self.what}")
        if info.compress_type not in METHODS:
            raise InputError(f"{self.path}: member {name!r} is compressed with method {info.compress_type} "
                             f"(only stored and deflate are read)")
        if info.file_size > cap:
            raise InputError(f"{self.path}: member {name!r} inflates to {size_text(info.file_size)}, over the "
                             f"{size_text(cap)} this reader takes")
        if info.file_size > self.max_ratio * max(info.compress_size, 1) and info.file_size > 1 << 16:
            raise InputError(f"{self.path}: member {name!r} claims {size_text(info.file_size)} from "
                             f"{size_text(info.compress_size)} (over {self.max_ratio}:1, more than deflate can reach)")
        return info

    def read(self, name: str, cap: int) -> bytes:
        """The whole member, checked (at most `cap` bytes inflated)."""
        self.check(name, cap)
        return b"".join(self.stream(name, cap))

    def stream(self, name: str, cap: int, block: int = 1 << 20) -> Iterator[bytes]:
        """The member in pieces of at most `block` bytes, checked first; a damaged member: InputError."""
        info = self.check(name, cap)
        try:
            with self.zip.open(info) as fh:
                while data := fh.read(block):
                    yield data
        except _READ_ERRORS as e:
            raise InputError(f"{self.path}: member {name!r} cannot be read ({str(e)[:120]})") from None
