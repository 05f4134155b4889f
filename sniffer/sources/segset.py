"""Several capture files as one capture: a rotated capture's folder, its index, or files given in order.

    src = capture_source(["cab3/"])          # or ["a.mcap", "b.mcap"], or ["cab3/index.json"]; one file: FileSource
    info = src.open()                        # the first file's metadata; every file checked: same line
    for ev in src.events(): ...              # one stream: frames numbered on, one clock

The files are replayed in time order (the segments of one capture share its
clock; files of different captures are put on the first one's clock by their
wall-clock anchors, or one after another when they have none).  Between two
captures (a restart) and where a segment of one capture is missing (deleted by
--keep, lost) a Gap marks the hole, so the first frame after it says so; the Gap
carries what the decoders knew where the next file starts (its recorded
`decoder_state`, decoders/carry.py), so its values are scaled and named as the
capture had them.  Across segments that follow each other the decoders go on as
they are (one pipeline).  A segment that holds nothing recorded (empty, or its
header alone: the next segment of a capture killed right after a rotation) is
skipped with a line in `notes`, not damage.  A killed segment cut before its
metadata is skipped and listed in `damage`; damage inside a file is listed as
its reader says.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from dataclasses import replace

from decoders.carry import KEY

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.formats.mcap.segments import INDEX_NAME, set_files
from sniffer.events import CaptureError
from sniffer.formats.reading import EmptyCapture
from sniffer.formats.reading import gap_before
from sniffer.sources.files import FileSource


def is_set(paths) -> bool:
    """True when `paths` name more than one capture file: several, a folder, or a segment index."""
    paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    return len(paths) > 1 or any(os.path.isdir(p) or os.path.basename(os.fspath(p)) == INDEX_NAME for p in paths)


def capture_source(paths, fmt: str = "auto", logic=None):
    """FileSource for one capture file, SetSource for a set (see is_set); `logic`: a sigrok .sr file's channels."""
    if not is_set(paths):
        return FileSource(paths if isinstance(paths, (str, os.PathLike)) else paths[0], fmt, logic)
    paths = [os.fspath(p) for p in ([paths] if isinstance(paths, (str, os.PathLike)) else paths)]
    return SetSource(paths, fmt)


def _line(info: CaptureInfo) -> tuple:
    return info.baud, info.parity, info.stopbits, info.databits, info.protocol


def _shift(ev, off: int):
    """The event `off` ns later (its link and channel kept)."""
    if type(ev) is Chunk:
        times = None if ev.byte_t_ns is None else tuple(t + off for t in ev.byte_t_ns)
        return replace(ev, t_ns=ev.t_ns + off, byte_t_ns=times)
    if type(ev) is Tick:
        return replace(ev, t_ns=ev.t_ns + off)
    return replace(ev, t_ns=ev.t_ns + off, t_end_ns=ev.t_end_ns + off)


class SetSource:
    """The files of a set as one stream of events (see the module doc)."""

    def __init__(self, paths: list[str], fmt: str = "auto") -> None:
        self.paths = paths
        self.path = ", ".join(paths) if len(paths) <= 3 else f"{paths[0]} ... ({len(paths)} paths)"
        self.format = fmt
        self.damage: list[str] = []
        self.unfinished: list[str] = []
        self.notes: list[str] = []  # segments skipped that held nothing (not damage)
        self.files: list[tuple[str, CaptureInfo]] = []
        self._info: CaptureInfo | None = None
        self._stop = threading.Event()
        self._current: FileSource | None = None
        self._sizes: list[int] = []
        self._done_bytes = 0

    def open(self) -> CaptureInfo:
        if self._info is not None:
            return self._info
        files = set_files(self.paths)
        if not files:
            raise CaptureError(f"{self.path}: no capture files there (no segments, no .mcap)")
        infos = []
        for path in files:
            src = FileSource(path, self.format)
            try:
                info = src.open()
            except EmptyCapture as e:
                if len(files) == 1:
                    raise
                self.notes.append(f"{e}: skipped (a segment that holds nothing: its capture was stopped as it "
                                  "opened it)")
                continue
            except CaptureError as e:
                if len(files) == 1 or not path.endswith(".part"):
                    raise
                self.damage.append(f"{e} (skipped)")  # a killed segment cut before its metadata
                continue
            finally:
                src.close()
            infos.append((path, info))
        if not infos:
            raise EmptyCapture(f"{self.path}: none of its {len(files)} capture files holds anything recorded")
        first_path, first = infos[0]
        for path, info in infos[1:]:
            if _line(info) != _line(first):
                raise CaptureError(f"{path}: recorded at {_describe(info)}, but {first_path} at {_describe(first)}: "
                                   f"replay them separately")
        infos = self.files = self._order(infos)
        base = CaptureInfo.from_dict(infos[0][1].to_dict())
        for key in ("segment", "segment_t_ns", "mcap_unfinished"):
            base.extra.pop(key, None)
        base.extra["set_files"] = len(infos)
        base.source = base.source or infos[0][0]
        self._sizes = [_size(p) for p, _ in infos]
        self._info = base
        return base

    @staticmethod
    def _order(infos: list[tuple[str, CaptureInfo]]) -> list[tuple[str, CaptureInfo]]:
        """Time order: by wall clock when every file has one; else captures in the order given, each
        capture's segments by their start."""
        def start(info):
            return info.extra.get("segment_t_ns", info.t0_ns)

        if all(info.wall_anchor_ns for _, info in infos):
            return sorted(infos, key=lambda pi: pi[1].wall_anchor_ns + start(pi[1]) - pi[1].t0_ns)
        rank: dict = {}
        for path, info in infos:
            rank.setdefault(info.extra.get("capture_id") or path, len(rank))
        return sorted(infos, key=lambda pi: (rank[pi[1].extra.get("capture_id") or pi[0]], start(pi[1])))

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        self.open()
        return self._events()

    def _events(self) -> Iterator[Chunk | Tick | Gap]:
        base = self._info
        last_t: int | None = None
        prev: CaptureInfo | None = None
        off = 0
        for i, (path, info) in enumerate(self.files):
            if self._stop.is_set():
                return
            hole = self._hole(prev, info, path)
            if prev is None or not _same_capture(prev, info):
                off = self._offset(info, base, last_t)
            src = self._current = FileSource(path, self.format)
            try:
                src.open()
                first = True
                for ev in src.events():
                    if off:
                        ev = _shift(ev, off)
                    if first:
                        first = False
                        if hole and last_t is not None:
                            gap = gap_before(last_t, ev, hole)
                            state = info.extra.get(KEY)
                            yield replace(gap, state=state) if isinstance(state, dict) and state else gap
                    last_t = ev.t_end_ns if type(ev) is Gap else ev.t_ns
                    yield ev
            except CaptureError as e:
                self.damage.append(f"{e} (skipped)")
            finally:
                src.close()
                self.damage += [d for d in src.damage if d not in self.damage]
                if src._info is not None and src._info.extra.get("mcap_unfinished"):
                    self.unfinished.append(path)
                self._done_bytes += self._sizes[i]
            prev = info

    @staticmethod
    def _offset(info: CaptureInfo, base: CaptureInfo, last_t: int | None) -> int:
        """What to add to a file's times to put them on the set's clock (the first file's)."""
        if info.wall_anchor_ns and base.wall_anchor_ns:
            off = (info.wall_anchor_ns - info.t0_ns) - (base.wall_anchor_ns - base.t0_ns)
        else:
            off = 0 if info.t0_ns == base.t0_ns else base.t0_ns - info.t0_ns
        start = info.extra.get("segment_t_ns", info.t0_ns) + off
        if last_t is not None and start <= last_t:  # no wall clock, or clocks that overlap: one after another
            off += last_t + 1 - start
        return off

    @staticmethod
    def _hole(prev: CaptureInfo | None, info: CaptureInfo, path: str) -> str:
        """Why there is a hole before this file ('' for the next segment of the same capture)."""
        if prev is None:
            return ""
        name = os.path.basename(path)
        if not _same_capture(prev, info):
            return f"another capture starts ({name})"
        a, b = prev.extra.get("segment"), info.extra.get("segment")
        if isinstance(a, int) and isinstance(b, int) and b != a + 1:
            which = f"segment {a + 1} is" if b == a + 2 else f"segments {a + 1}..{b - 1} are"
            return f"{which} missing (before {name})"
        return ""

    def stop(self) -> None:
        self._stop.set()
        if self._current is not None:
            self._current.stop()

    def close(self) -> None:
        self._stop.set()
        if self._current is not None:
            self._current.close()

    def position(self) -> tuple[int, int] | None:
        """(bytes read so far, the files' sizes) for a progress bar, or None before open()."""
        if self._info is None:
            return None
        total = sum(self._sizes)
        cur = self._current.position() if self._current is not None else None
        return self._done_bytes + (cur[0] if cur else 0), total


def _same_capture(a: CaptureInfo, b: CaptureInfo) -> bool:
    """Two segments of one capture (files without a capture id are captures of their own)."""
    cid = a.extra.get("capture_id")
    return cid is not None and cid == b.extra.get("capture_id") and a.t0_ns == b.t0_ns


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def _describe(info: CaptureInfo) -> str:
    return f"{info.baud} {info.databits}{info.parity}{info.stopbits} {info.protocol}"


def replay_source(spec):
    """The capture of a replay-like command: one file (a killed capture's part file when only that is
    there), or a set read as one capture: several files, a rotated capture's folder or its index."""
    from sniffer.formats.outputs import readable

    if is_set(spec.inputs or spec.input):
        return capture_source(spec.inputs, spec.input_format)
    path, note = readable(spec.input)
    if note:
        from sniffer.stderr import say

        say(f"note: {note}")
    return capture_source(path, spec.input_format, spec.logic)
