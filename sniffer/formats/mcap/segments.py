"""A capture kept as a set of MCAP segments in one folder: names, the index, retention, the flags.

Shared by the writer (formats/mcap/rotating.py), the reader (sources/segset.py) and
`sniffer status`; none of them imports another.

    cab3/                                  the capture's folder (--out with --rotate)
      cab3-20261125T104100Z-00001.mcap     a closed segment: a complete MCAP, replayable alone
      cab3-20261125T114100Z-00002.mcap
      cab3-20261125T124100Z-00003.mcap.part   the open one (a kill leaves it: repair or replay it)
      index.json                           the segments: file, time span, frames, bytes, state
      status.json                          the capture's status (sniffer.capture.status), every few seconds

A segment's name is its folder's name, the UTC wall time its first event was
recorded (the capture's wall anchor plus capture time; a simulated capture
has no wall clock and starts at 1970-01-01) and a sequence number that goes
on across restarts: names sort in time.  Every segment carries the capture's
metadata (the same t0 and wall anchor: one clock) plus `segment` and
`capture_id` in its `extra`.

`--rotate 1h`, `--rotate 100MB`, or both (`--rotate 1h,100MB` or the flag twice):
a new segment when the open one holds that much capture time or that many
bytes, whichever comes first.  `--keep 7d`, `--keep 20GB`, `--keep 48` (segments),
repeatable, all applying: the oldest closed segments are deleted first, the
open one never.
"""

from __future__ import annotations

import calendar
import json
import os
import re
import time
from dataclasses import asdict, dataclass, field

from sniffer.line import SettingsError
from sniffer.formats.outputs import write_json_atomic

INDEX_NAME = "index.json"
STATUS_NAME = "status.json"
LOCK_NAME = ".sniffer.lock"
INDEX_FORMAT = "sniffer.segments/1"
SEGMENT_RE = re.compile(r"(?P<prefix>.+)-(?P<time>\d{8}T\d{6}Z)-(?P<seq>\d{5,})\.mcap(?P<part>(?:\.\d+)?\.part)?\Z")
MIN_ROTATE_BYTES = 10**6  # each segment carries its own schemas, channels (one per register) and index: tens of kB
MIN_ROTATE_S = 1.0
_SIZE = re.compile(r"(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]i?b|b)\Z", re.I)
_SIZE_UNITS = {"b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12,
               "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}
_NS = 1_000_000_000


# ---------------------------------------------------------------- the flags
def parse_size(text: str) -> int | None:
    """Bytes of `100MB`, `1.5GB`, `512KiB` (kB, MB, GB, TB are powers of 10; KiB... of 2); None if not a size."""
    m = _SIZE.fullmatch(text.strip())
    return None if m is None else int(float(m.group(1)) * _SIZE_UNITS[m.group(2).lower()])


def parse_span(text: str) -> int | None:
    """Nanoseconds of `90s`, `30m`, `1.5h`, `7d`, `2w` (the flags' one time grammar: ns ... d, w); None if not a
    time span (a unit is required: a bare number is a size or a count here) or a negative one."""
    from sniffer.filterlang.values import BadValue, parse_duration

    try:
        ns = parse_duration(text.strip(), None)
    except BadValue:
        return None
    return int(round(ns)) if ns >= 0 else None


def _pieces(values) -> list[str]:
    return [p.strip() for v in (values or ()) for p in str(v).split(",") if p.strip()]


@dataclass(frozen=True)
class Rotate:
    """When the open segment is closed: after `span_ns` of capture time or `max_bytes` on disk (0: never)."""

    span_ns: int = 0
    max_bytes: int = 0

    @classmethod
    def parse(cls, values) -> Rotate | None:
        """--rotate values (`1h`, `100MB`, `1h,100MB`); None when not given; SettingsError for a bad one."""
        span = size = 0
        for p in _pieces(values):
            n, s = parse_size(p), parse_span(p)
            if n is not None:
                if n < MIN_ROTATE_BYTES:
                    raise SettingsError(f"--rotate {p}: segments of at least {size_text(MIN_ROTATE_BYTES)} (each "
                                        f"carries its own schemas, channels and index: tens of kB)")
                size = n
            elif s is not None:
                if s < MIN_ROTATE_S * _NS:
                    raise SettingsError(f"--rotate {p}: segments of at least {MIN_ROTATE_S:g} s")
                span = s
            else:
                raise SettingsError(f"--rotate {p[:40]!r}: a size (100MB, 2GB) or a time (30m, 1h, 1d)")
        return cls(span, size) if span or size else None

    def describe(self) -> str:
        parts = ([span_text(self.span_ns)] if self.span_ns else []) + ([size_text(self.max_bytes)]
                                                                         if self.max_bytes else [])
        return " or ".join(parts)


@dataclass(frozen=True)
class Keep:
    """Retention: closed segments older than `age_ns`, past `max_bytes` in all, or past `count` go (0: no limit)."""

    age_ns: int = 0
    max_bytes: int = 0
    count: int = 0

    @classmethod
    def parse(cls, values) -> Keep | None:
        """--keep values (`7d`, `20GB`, `48`); None when not given; SettingsError for a bad one."""
        age = size = count = 0
        for p in _pieces(values):
            if p.isdigit():
                count = int(p)
                if count < 1:
                    raise SettingsError("--keep 0: keep at least one segment")
            elif (n := parse_size(p)) is not None:
                size = n
            elif (s := parse_span(p)) is not None and s > 0:
                age = s
            else:
                raise SettingsError(f"--keep {p[:40]!r}: an age (7d, 12h), a size (20GB) or a number of segments")
        return cls(age, size, count) if age or size or count else None

    def describe(self) -> str:
        parts = [f"{span_text(self.age_ns)}"] if self.age_ns else []
        parts += [size_text(self.max_bytes)] if self.max_bytes else []
        parts += [f"{self.count} segments"] if self.count else []
        return ", ".join(parts)

    def to_delete(self, closed: list[Segment], now_ns: int, open_bytes: int = 0, open_count: int = 1
                  ) -> list[Segment]:
        """The closed segments (oldest first in `closed`) that go: the oldest first, until every limit holds
        (the open segment, `open_count` of them, counts in the size and the number but is never deleted)."""
        gone: list[Segment] = []
        left = list(closed)
        total = sum(s.bytes for s in left) + open_bytes
        while left:
            s = left[0]
            too_old = self.age_ns and now_ns - s.end_ns > self.age_ns
            too_big = self.max_bytes and total > self.max_bytes
            too_many = self.count and len(left) + open_count > self.count
            if not (too_old or too_big or too_many):
                break
            gone.append(left.pop(0))
            total -= s.bytes
        return gone


def limits(rotate: Rotate | None, keep: Keep | None) -> dict:
    """--rotate and --keep as numbers, for the status file: seconds, bytes, segments (0: no such limit)."""
    rotate, keep = rotate or Rotate(), keep or Keep()
    return {"rotate_s": rotate.span_ns / _NS, "rotate_bytes": rotate.max_bytes,
            "keep_s": keep.age_ns / _NS, "keep_bytes": keep.max_bytes, "keep_count": keep.count}


def held(rate: float, limit: dict) -> tuple[float, str] | None:
    """How much capture time the folder keeps when its segments grow by `rate` bytes a second (`limit`: limits()),
    and the --keep limit that decides it (the first to bite): (seconds, `14d` | `20GB` | `48 segments`); None when
    nothing is ever deleted (no --keep, or no rate to go by).  About: the open segment counts towards a size and
    a number too, and is never deleted."""
    def num(key: str) -> float:  # a limit read from a status file: a positive finite number, else none
        v = limit.get(key)
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            return 0.0
        try:
            v = float(v)
        except OverflowError:
            return 0.0
        return v if 0 < v < float("inf") else 0.0

    age, size, count = num("keep_s"), num("keep_bytes"), num("keep_count")
    if rate <= 0:
        return (age, span_text(int(age * _NS))) if age else None
    spans = [num("rotate_s"), num("rotate_bytes") / rate]
    segment = min((x for x in spans if x), default=0.0)  # a segment's capture time at this rate
    out = []
    if age:
        out.append((age, span_text(int(age * _NS))))
    if size:
        out.append((size / rate, size_text(int(size))))
    if count and segment:
        out.append((count * segment, f"{int(count)} segments"))
    return min(out) if out else None


def span_text(ns: int) -> str:
    s = ns / _NS
    for unit, n in (("d", 86_400), ("h", 3_600), ("m", 60)):
        if s >= n and s % n == 0:
            return f"{s / n:g}{unit}"
    return f"{s:g}s"


def size_text(n: int) -> str:
    for unit, k in (("GB", 10**9), ("MB", 10**6), ("kB", 10**3)):
        if n >= k:
            return f"{n / k:.3g}{unit}" if n % k else f"{n // k}{unit}"
    return f"{n}B"


# ---------------------------------------------------------------- names and the index
def folder_for(out: str) -> str:
    """The capture's folder for --out with --rotate: `cab3.mcap` and `cab3/` both name `cab3`."""
    out = out.rstrip("/") or "/"
    return out[:-5] if out.endswith(".mcap") else out


def segment_name(prefix: str, wall_ns: int, seq: int) -> str:
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(max(0, wall_ns) // _NS))
    return f"{prefix}-{stamp}-{seq:05d}.mcap"


@dataclass
class Segment:
    """One segment as the index lists it (times are wall-clock ns; `t_start`/`t_end` capture seconds)."""

    file: str
    seq: int
    capture_id: str = ""
    start_ns: int = 0
    end_ns: int = 0
    t_start: float = 0.0
    t_end: float = 0.0
    frames: int = 0
    bytes: int = 0
    state: str = "closed"  # closed | open (being written) | killed (a part file a dead capture left: repairable)
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict) -> Segment:
        known = {k: d[k] for k in cls.__dataclass_fields__ if k in d}
        return cls(**known)

    def to_dict(self) -> dict:
        return asdict(self)


def read_json(path: str) -> dict | None:
    """A JSON object from `path`, or None if it is missing or not one."""
    try:
        with open(path, encoding="utf-8") as fh:
            d = json.load(fh)
    except (OSError, ValueError):
        return None
    return d if isinstance(d, dict) else None


def write_index(folder: str, segments: list[Segment]) -> None:
    write_json_atomic(os.path.join(folder, INDEX_NAME),
                      {"format": INDEX_FORMAT, "segments": [s.to_dict() for s in segments]})


def read_index(folder: str) -> list[Segment]:
    """The index's segments, reconciled with the folder: files gone are left out, segment files the
    index does not list are added (times from the name and mtime), a dead capture's open segment
    (only its part file is there) is `killed`.  Sorted by sequence number."""
    d = read_json(os.path.join(folder, INDEX_NAME)) or {}
    listed: dict[str, Segment] = {}
    for item in d.get("segments") or ():
        if isinstance(item, dict) and isinstance(item.get("file"), str):
            try:
                listed[item["file"]] = Segment.from_dict(item)
            except TypeError:
                continue
    try:
        names = os.listdir(folder)
    except OSError:
        names = []
    on_disk: dict[str, str] = {}  # final name -> the name on disk
    for name in names:
        m = SEGMENT_RE.match(name)
        if m:
            final = name[: m.start("part")] if m.group("part") else name
            if final not in on_disk or not m.group("part"):
                on_disk[final] = name
    out = []
    for final, name in on_disk.items():
        seg = listed.get(final)
        path = os.path.join(folder, name)
        try:
            st = os.stat(path)
        except OSError:
            continue
        if seg is None:
            m = SEGMENT_RE.match(final)
            start = calendar.timegm(time.strptime(m.group("time"), "%Y%m%dT%H%M%SZ")) * _NS
            seg = Segment(final, int(m.group("seq")), start_ns=start, end_ns=int(st.st_mtime * _NS))
        seg.bytes = st.st_size
        if name != final:
            seg.state = "open" if seg.state == "open" else "killed"
            seg.extra["part"] = name
        elif seg.state != "closed":
            seg.state = "closed"  # renamed into place by a capture that died before it wrote the index
        out.append(seg)
    out.sort(key=lambda s: s.seq)  # numbered on across restarts: time order, with a wall clock or without
    return out


def set_files(paths: list[str]) -> list[str]:
    """The files a replay of `paths` reads, in order: a folder (or its index.json) gives its segments
    (part files of open or killed ones included); files are taken as given, in the order given."""
    files: list[str] = []
    for p in paths:
        folder = p if os.path.isdir(p) else (os.path.dirname(p) or ".") if os.path.basename(p) == INDEX_NAME \
            else None
        if folder is None:
            files.append(p)
            continue
        segs = read_index(folder)
        files += [os.path.join(folder, s.extra.get("part") or s.file) for s in segs]
        if not segs:
            files += sorted(os.path.join(folder, n) for n in os.listdir(folder) if n.endswith(".mcap"))
    return files
