"""Files the sniffer writes: under a temporary name in their folder, renamed into place when complete.

    out = Output("cabinet3.mcap", inputs=["capture.csv"])   # checks now: folder, not an input
    sink = McapSink(out.part)                              # the file is written as cabinet3.mcap.part
    ...
    out.commit()      # rename over cabinet3.mcap (the old file, if any, stays until this moment)
    out.discard()     # or: remove the part file, cabinet3.mcap untouched

So a failed or interrupted command never leaves half a file under the name
the user asked for, and never empties a file before it has read its input.
An output that is also one of the command's inputs is refused up front.
The part file of a capture that was killed stays on disk (`NAME.part`):
`sniffer replay` and `sniffer repair` read it.
"""

from __future__ import annotations

import json
import os

from sniffer.events import CaptureError

PART = ".part"


class OutputError(CaptureError):
    """An output path that cannot be used: one line for the user, exit code 2."""


def shown(path: str, limit: int = 200) -> str:
    """A path (or any user text) as it goes into an error line: at most `limit` characters."""
    s = os.fspath(path)
    return s if len(s) <= limit else s[: limit - 3] + "..."


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


class Output:
    """One file to write atomically (see the module doc)."""

    def __init__(self, path: str | os.PathLike[str], *, inputs=(), what: str = "--out") -> None:
        self.path = os.fspath(path)
        p = shown(self.path)
        if not self.path:
            raise OutputError(f"{what}: empty file name")
        folder = os.path.dirname(os.path.abspath(self.path))
        if not os.path.isdir(folder):
            raise OutputError(f"{p}: folder {shown(folder)} does not exist")
        if os.path.isdir(self.path):
            raise OutputError(f"{p}: is a folder, not a file name")
        if os.path.exists(self.path) and not os.path.isfile(self.path):
            raise OutputError(f"{p}: exists and is not a regular file (not writing over it)")
        for src in inputs:
            if src and (_same_file(self.path, os.fspath(src)) or _same_file(self.path + PART, os.fspath(src))):
                raise OutputError(f"{p}: is also an input of this command; write to another file")
        if not os.access(folder, os.W_OK):
            raise OutputError(f"{p}: folder {shown(folder)} is not writable")
        self.part = self._free_part_name()
        self.done = False

    def _free_part_name(self) -> str:
        """`NAME.part`, or `NAME.2.part` ... when a killed run left its part file there (never reuse it)."""
        cand = self.path + PART
        n = 2
        while os.path.lexists(cand):
            cand = f"{self.path}.{n}{PART}"
            n += 1
        return cand

    def commit(self) -> None:
        """Rename the finished part file over the output (atomic on one file system)."""
        if self.done:
            return
        self.done = True
        if os.path.exists(self.part):
            os.replace(self.part, self.path)

    def discard(self) -> None:
        """Remove the part file; the output path keeps what it held before."""
        if self.done:
            return
        self.done = True
        try:
            os.remove(self.part)
        except FileNotFoundError:
            pass


def left_behind(path: str) -> str | None:
    """The part file a killed run left for `path`, if there is one (the newest, when several)."""
    cands = [c for c in (path + PART, *(f"{path}.{n}{PART}" for n in range(2, 10))) if os.path.isfile(c)]
    return max(cands, key=os.path.getmtime) if cands else None


def readable(path: str) -> tuple[str, str | None]:
    """(the file to read for `path`, a note): a capture killed before it was renamed into place is read
    from its part file, and the note says so."""
    if os.path.lexists(path):
        return path, None
    part = left_behind(path)
    if part is None:
        return path, None
    return part, (f"{shown(path)} is not there, but {shown(part)} is: a capture that did not end cleanly "
                  f"(killed?); reading that")


def write_json_atomic(path: str, obj) -> None:
    """Write `obj` as JSON to `path` through a temporary file renamed over it (a reader never sees half)."""
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(obj, fh, indent=1)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise
