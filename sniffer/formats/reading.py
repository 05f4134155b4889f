"""What every capture reader shares besides sniffer.inputs' rules: a bounded damage log, gaps, quoting bad input."""

from __future__ import annotations

from sniffer.events import CaptureError


class EmptyCapture(CaptureError):
    """A capture file that holds nothing recorded: empty, or cut off before its capture info (a capture
    killed as it began, or right after a rotation opened its next segment).  Alone it is nothing to replay;
    in a set of segments it is skipped with a note, not damage."""


QUOTE_LIMIT = 200


def quote(text: str, limit: int = QUOTE_LIMIT) -> str:
    """repr() of a piece of bad input, cut to about `limit` characters (a 100 kB field is not echoed)."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text):,} characters)"


def file_position(fh, size: int) -> tuple[int, int] | None:
    """(bytes read so far, file size) of an open reader's file, for a progress bar; None once closed."""
    if fh is None or fh.closed:
        return None
    return fh.tell(), size


class DamageLog:
    """The `damage` list of a reader, bounded: a file with a million bad rows lists the first few.

    `add(kind, sentence)` appends up to `per_kind` sentences of one kind;
    `finish()` adds one line per kind saying how many more there were.
    """

    def __init__(self, target: list[str], per_kind: int = 10) -> None:
        self.lines = target
        self.per_kind = per_kind
        self._counts: dict[str, int] = {}
        self._finished = False

    def add(self, kind: str, sentence: str) -> None:
        n = self._counts.get(kind, 0) + 1
        self._counts[kind] = n
        if n <= self.per_kind:
            self.lines.append(sentence)

    def __len__(self) -> int:
        return sum(self._counts.values())

    def finish(self, path: str) -> None:
        if self._finished:
            return
        self._finished = True
        for kind, n in self._counts.items():
            if n > self.per_kind:
                self.lines.append(f"{path}: {n - self.per_kind:,} more {kind} not listed ({n:,} in all)")


SLOWEST_CHAR_NS = 100_000_000  # 100 ms a character: slower than any serial line we decode (110 baud 8N1)


def gap_before(last_t: int | None, ev, reason: str):
    """The Gap to yield just before event `ev` when input was lost since time `last_t`.

    The pipeline marks the first frame with t_ns >= t_end_ns, so t_end_ns is
    the earliest time a frame of `ev` can start: its first byte (per-byte),
    or its read time less 100 ms per byte (per-read: the framer dates the
    bytes back from the read time at the line's character time).
    """
    from sniffer.events import Chunk, Gap

    if type(ev) is Chunk:
        end = ev.byte_t_ns[0] if ev.byte_t_ns else ev.t_ns - len(ev.data) * SLOWEST_CHAR_NS
        if ev.byte_t_ns is None and last_t is not None:
            end = min(max(end, last_t + 1), ev.t_ns)
    else:
        end = ev.t_ns
    start = end if last_t is None else min(last_t, end)
    return Gap(start, end, reason)
