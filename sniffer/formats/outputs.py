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
`sniffer replay` and `sniffer repair` read it; so does one a full disk cut
short (`keep_part()`: never renamed over the name asked for, since it lacks
its end).

Modes.  Every file is created at most 0644 (FILE_MODE, and less where the
umask says so), one holding credentials 0600 (`private=True`), every folder
at most 0755 (`make_folders`): a `umask 000` shell does not make a capture,
a status file or the folder holding them writable by everyone.  `claim()`
creates the part file so (O_EXCL: never through something already there);
`commit()` takes away any bit past the mode, whoever created the file.
"""

from __future__ import annotations

import errno
import json
import os
import stat

from sniffer.events import CaptureError

PART = ".part"
FILE_MODE = 0o644  # the most a file the sniffer writes is created with (the umask may take more away)
PRIVATE_MODE = 0o600  # a file that holds credentials
FOLDER_MODE = 0o755  # a folder the sniffer makes (a capture's segments, trigger windows, a dataset's partitions)


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


def _reads(src: str) -> list[str]:
    """The files a command reads for input `src`: itself, or a rotated capture folder's segments, their part
    files and its index (every .mcap, .part and .json file in it: formats/mcap/segments.py names them)."""
    if not os.path.isdir(src):
        return [src]
    try:
        return [os.path.join(src, n) for n in sorted(os.listdir(src)) if n.endswith((".mcap", ".part", ".json"))]
    except OSError:
        return []


def check_output(path: str, *, inputs=(), what: str = "--out", outputs=()) -> None:
    """OutputError (one line) unless `path` can take a file this command writes: its folder exists and is
    writable, nothing but a regular file is there, it is none of the command's `inputs` (files, or the
    folders of rotated captures) and none of its other `outputs` (nor their part files)."""
    p = shown(path)
    if not path:
        raise OutputError(f"{what}: empty file name")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OutputError(f"{p}: folder {shown(folder)} does not exist")
    if os.path.isdir(path):
        raise OutputError(f"{p}: is a folder, not a file name")
    if not regular_or_absent(path):
        raise OutputError(f"{p}: exists and is not a regular file (not writing over it)")
    for src in inputs:
        src = os.fspath(src) if src else ""
        if src and any(_same_file(path, f) or _same_file(path + PART, f) for f in _reads(src)):
            raise OutputError(f"{p}: is also an input of this command; write to another file")
    for other in outputs:
        other = os.fspath(other) if other else ""
        if other and (_same_file(path, other) or _same_file(path, other + PART)):
            raise OutputError(f"{what} {p}: is also another output of this command; write to another file")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"{p}: folder {shown(folder)} is not writable")


class Output:
    """One file to write atomically (see the module doc)."""

    def __init__(self, path: str | os.PathLike[str], *, inputs=(), what: str = "--out",
                 private: bool = False) -> None:
        self.path = os.fspath(path)
        self.mode = PRIVATE_MODE if private else FILE_MODE
        check_output(self.path, inputs=inputs, what=what)
        self.part = self._free_part_name()
        self.done = False
        self.state = "writing"  # then "committed" (under its name), "kept" (left as the part file), "discarded"

    def _free_part_name(self) -> str:
        """`NAME.part`, or `NAME.2.part` ... when a killed run left its part file there (never reuse it)."""
        cand = self.path + PART
        n = 2
        while os.path.lexists(cand):
            cand = f"{self.path}.{n}{PART}"
            n += 1
        return cand

    def claim(self) -> str:
        """Create the part file (empty, at most `mode`) for a writer that opens it by name; its path."""
        fd = os.open(self.part, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), self.mode)
        os.close(fd)
        return self.part

    def write_text(self, text: str) -> None:
        """The whole file's text (UTF-8) into the part file; an OSError names the output, not its part."""
        try:
            with open(self.claim(), "w", encoding="utf-8") as fh:
                fh.write(text)
        except OSError as e:
            raise OSError(e.errno, f"cannot write: {e.strerror or e}", self.path) from None

    def commit(self) -> None:
        """Rename the finished part file over the output (atomic on one file system)."""
        if self.done:
            return
        self.done = True
        self.state = "committed"
        if os.path.exists(self.part):
            cap_mode(self.part, self.mode)
            os.replace(self.part, self.path)

    def keep_part(self) -> bool:
        """Leave the part file as it is (cut short: never under the name asked for), for replay or repair;
        one with nothing in it is removed.  True if it was kept."""
        if self.done:
            return self.state == "kept"
        try:
            size = os.path.getsize(self.part)
        except OSError:
            size = 0
        if not size:
            self.discard()
            return False
        self.done = True
        self.state = "kept"
        cap_mode(self.part, self.mode)
        return True

    def discard(self) -> None:
        """Remove the part file; the output path keeps what it held before."""
        if self.done:
            return
        self.done = True
        self.state = "discarded"
        try:
            os.remove(self.part)
        except FileNotFoundError:
            pass


def make_folders(path: str) -> None:
    """`os.makedirs(path, exist_ok=True)`, each folder made at most FOLDER_MODE (the umask may take more)."""
    missing = []
    p = os.path.abspath(path)
    while not os.path.isdir(p):
        missing.append(p)
        parent = os.path.dirname(p)
        if parent == p:
            break
        p = parent
    for folder in reversed(missing):
        try:
            os.mkdir(folder, FOLDER_MODE)
        except FileExistsError:
            if not os.path.isdir(folder):
                raise


def cap_mode(path: str, mode: int = FILE_MODE) -> None:
    """Take from `path`'s permissions every bit past `mode` (never adds one)."""
    try:
        have = os.stat(path).st_mode & 0o7777
        if have & ~mode:
            os.chmod(path, have & mode)
    except OSError:
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


def regular_or_absent(path: str) -> bool:
    """True if nothing is at `path` or a regular file is (what an output may replace)."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except FileNotFoundError:
        return True
    except OSError:
        return False


def write_json_atomic(path: str, obj, mode: int = FILE_MODE) -> None:
    """Write `obj` as JSON to `path` through a temporary file renamed over it (a reader never sees half).

    Never over something that is not a regular file (a FIFO, a device, a folder: OSError)."""
    if not regular_or_absent(path):
        raise OSError(errno.EEXIST, "exists and is not a regular file (not writing over it)", path)
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        try:
            os.remove(tmp)  # one a killed run of the same pid left: O_EXCL below never writes through it
        except FileNotFoundError:
            pass
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), mode)
        with open(fd, "w", encoding="utf-8") as fh:
            json.dump(obj, fh, indent=1)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise


def lock_file(fd: int) -> bool:
    """Take fd's exclusive lock without waiting: True taken (held until fd closes), False another process holds
    it.  flock where the system has it; Windows locks the file's first byte (msvcrt); a system with neither has
    no locks between processes, and every lock is taken (one sniffer at a time is then the user's to keep)."""
    try:
        import fcntl
    except ImportError:
        fcntl = None
    if fcntl is not None:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            if e.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                return False
            raise
        return True
    try:
        import msvcrt
    except ImportError:
        return True
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        return False
    return True
