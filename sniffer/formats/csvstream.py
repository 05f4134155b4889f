"""Streaming reader shared by the byte CSV and the Saleae CSV: one row per byte.

Memory stays flat whatever the file's length: rows are read line by line,
merged by time through a bounded reorder window and cut into Chunks as they
come.  Two passes over the file: `open()` reads until it knows whether times
are per byte or per read (consecutive rows of one channel sharing a time
are a USB adapter's reads), `events()` reads again and yields.

What is fatal (CaptureError from open(), one line) and what is damage (the
row is skipped, a sentence goes to `damage`, a Gap is yielded in its place
and reading goes on):

* fatal: the file cannot be opened, the header is not this format's, the
  header line is not UTF-8 text, or no row at all is readable (a garbage
  file: the message quotes its first bad row with file:line);
* damage: any single row that does not parse (a time that is not a number,
  out of range, NaN/inf; a byte outside 00..ff; a field over csv's 131,072
  character limit; a line that is not UTF-8; an export cut mid-row at the
  end), and a row whose time is earlier than rows already replayed more
  than the reorder window ago (it is replayed at the last time replayed:
  its byte is kept, its time is not; no Gap, as nothing is missing).
An I/O error in the middle of the file ends the replay with a damage line;
what was read stays.
"""

from __future__ import annotations

import codecs
import csv
from itertools import chain
from bisect import insort_right
from operator import itemgetter
import os
from collections.abc import Iterator

from sniffer.events import CaptureInfo, Chunk, Gap
from sniffer.events import CaptureError
from sniffer.formats.reading import DamageLog, gap_before, quote
from sniffer.inputs import open_regular

PER_BYTE_CHUNK = 4096  # per-byte chunks: up to this many bytes of one channel
REORDER_WINDOW = 8192  # rows held back to merge channels recorded as separate columns of time
MAX_LINE = 1 << 20  # a longer "line" is read in pieces (each one a bad row)
BATCH = 512  # rows handed from stage to stage in one list
BLOCK = 1 << 16  # bytes read at a time

Row = tuple[int, str, int, "str | None"]  # (t_ns, channel, byte, flag)
_time = itemgetter(0)


class _Lines:
    """Decoded lines of a binary file, read in blocks, counting bytes read.

    A block is decoded in one call and split at "\n" (as readline splits); a block that is not
    UTF-8 is decoded line by line and its bad lines become empty lines, their numbers in
    `bad_lines`.  A line longer than MAX_LINE is handed over in pieces (each one a bad row).
    `last_line` is the number of the file's last line once the end was read.
    """

    def __init__(self, fh) -> None:
        self.fh = fh
        self.bytes_read = 0
        self.bad_lines: set[int] = set()
        self.last_line: int | None = None

    def __iter__(self) -> Iterator[str]:
        return chain.from_iterable(self._blocks())

    def _blocks(self) -> Iterator[list[str]]:
        read = self.fh.read
        pending = b""
        lineno = 0
        first = True
        while True:
            block = read(BLOCK)
            self.bytes_read += len(block)
            if first and block:
                first = False
                if block.startswith(codecs.BOM_UTF8):
                    block = block[3:]
            data = pending + block if pending else block
            if not block:  # the end: what is left is the last line, without its newline
                if data:
                    self.last_line = lineno + 1
                    yield self._decode(data, lineno)
                else:
                    self.last_line = lineno
                return
            cut = data.rfind(b"\n") + 1
            if not cut:
                if len(data) < MAX_LINE:
                    pending = data
                    continue
                cut = MAX_LINE  # a piece of a very long line
            pending = data[cut:]
            lines = self._decode(data[:cut], lineno)
            lineno += len(lines)
            yield lines

    def _decode(self, data: bytes, lineno: int) -> list[str]:
        """Lines lineno + 1... of `data` (whole lines, but for a MAX_LINE piece) as text, each with
        its newline: the block decoded in one call, else line by line (bad ones empty)."""
        try:
            lines = data.decode("utf-8").split("\n")
        except UnicodeDecodeError:
            lines = None
        if lines is not None:
            last = lines.pop()  # "" after the final newline, or a piece without one
            lines = [x + "\n" for x in lines]
            if last:
                lines.append(last)
            return lines
        raws = data.split(b"\n")
        last = raws.pop()
        raws = [r + b"\n" for r in raws] + ([last] if last else [])
        out = []
        for k, r in enumerate(raws, lineno + 1):
            try:
                out.append(r.decode("utf-8"))
            except UnicodeDecodeError:
                self.bad_lines.add(k)
                out.append("\n")  # an empty row in its place: the caller reports it
        return out


class CsvRowSource:
    """Base of the CSV readers: a subclass parses the header and the rows."""

    kind = "CSV"

    def __init__(self, path: str | os.PathLike[str], damage: list[str] | None = None) -> None:
        self.path = os.fspath(path)
        self.damage: list[str] = [] if damage is None else damage
        self.info: CaptureInfo | None = None
        self.per_read = False
        self.t_offset = 0
        self.channels: set[str] = set()
        self._lines: _Lines | None = None
        self._fh = None
        self._size = 0
        self._first_bad: str | None = None

    # -- to be provided by the format -------------------------------------------------------
    def parse_header(self, header: list[str]) -> None:
        """Check the header row (lower-cased, stripped) and note the columns; CaptureError if foreign."""
        raise NotImplementedError

    def parse_row(self, row: list[str]) -> Row | None:
        """One data row -> (t_ns, channel, byte, flag), None to skip it quietly; ValueError if bad."""
        raise NotImplementedError

    def make_info(self) -> CaptureInfo:
        raise NotImplementedError

    # -- the reader -----------------------------------------------------------------------------
    def open(self) -> CaptureInfo:
        """First pass: header, time source, first rows.  CaptureError for what cannot be replayed."""
        if self.info is not None:
            return self.info
        log = DamageLog([])
        good = 0
        prev: tuple[int, str] | None = None
        with open_regular(self.path) as fh:
            self._size = os.fstat(fh.fileno()).st_size
            for item in _items(_merge(self._rows(fh, log), log, self.path)):
                if item[2] is None:  # a gap marker: bad rows before this one
                    continue
                if item[1] < 0:  # replayed late at an earlier row's time: says nothing about reads
                    prev = None
                    continue
                if good == 0:
                    self.t_offset = self.first_time_offset(item[0])
                good += 1
                self.channels.add(item[2])
                key = (item[0], item[2])
                if key == prev:
                    self.per_read = True
                    break
                prev = key
        if good == 0:
            if self._first_bad:
                raise CaptureError(f"{self._first_bad}; no row of this {self.kind} is readable")
            raise CaptureError(f"{self.path}: no serial bytes in this {self.kind} (no data rows)")
        self.info = self.make_info()
        return self.info

    def first_time_offset(self, t_first: int) -> int:
        """Added to every time (Saleae shifts a triggered capture that starts before 0)."""
        return 0

    def position(self) -> tuple[int, int] | None:
        return None if self._lines is None else (self._lines.bytes_read, self._size)

    def events(self) -> Iterator[Chunk | Gap]:
        """Second pass: the Chunks (and a Gap where rows were skipped), lazily."""
        self.open()
        log = DamageLog(self.damage)
        fh = open_regular(self.path)
        self._fh = fh
        try:
            yield from _chunks(_merge(self._rows(fh, log), log, self.path), self.per_read, self.channels)
        finally:
            log.finish(self.path)
            self.close()
            if self.info is not None and "channels" in self.info.extra:
                self.info.extra["channels"] = sorted(self.channels)

    def close(self) -> None:
        fh, self._fh = self._fh, None
        if fh is not None:
            fh.close()

    def _bad(self, log: DamageLog, sentence: str) -> None:
        if self._first_bad is None:
            self._first_bad = sentence
        log.add("bad rows", sentence + ": skipped")

    def _rows(self, fh, log: DamageLog) -> Iterator[list[tuple]]:
        """Lists (up to BATCH) of (t_ns, seq, channel, byte, flag, lineno) in file order; channel None =
        bad rows before.  Lists, not rows one by one: each stage after this one loops over a list
        instead of resuming a generator for every byte (a third of the reader's time).

        The header is checked first (a bad one is fatal: CaptureError); after it no row is fatal.  Each
        row goes through the format's `parse_row` (None: a row that carries no byte).  A row that does
        not parse, a line that is not UTF-8 (`_Lines` hands an empty line in its place and notes its
        number) and a csv.Error are damage: a sentence in `log`, and one marker row (channel None, byte =
        the first bad line number) put before the next good row, or at the end, so the stages after this
        one yield one Gap for a run of bad rows.  A csv.Error ends csv.reader's `for` loop: the `while`
        resumes it at the next row.  An OSError ends the reading, what was read kept.  A short last row
        is bad only where the file does not end with a newline (an export cut mid-row).  `t_offset`
        (`first_time_offset`: a Saleae capture triggered before 0 starts at 0) is added here, once."""
        lines = _Lines(fh)
        self._lines = lines
        reader = csv.reader(lines)
        path = self.path
        try:
            header = next(reader, None)
        except csv.Error as e:
            raise CaptureError(f"{path}:1: not a {self.kind} ({e})") from None
        except OSError as e:
            raise CaptureError(f"{path}: {e.strerror or e}") from None
        if 1 in lines.bad_lines:
            raise CaptureError(f"{path}: not a text CSV file (its first line is not UTF-8)")
        self.parse_header([h.strip().lower() for h in header or []])
        ncols = len(header or [])
        seq = 0
        out: list[tuple] = []
        bad_since: int | None = None
        offset = self.t_offset
        parse = self.parse_row
        next_yield = BATCH  # seq at which the list so far is handed on
        bad_lines = lines.bad_lines
        append = out.append
        while True:  # the for loop below runs to the end; a csv.Error resumes it at the next row
            try:
                for row in reader:
                    lineno = reader.line_num
                    if lineno in bad_lines:
                        bad_since = bad_since or lineno
                        self._bad(log, f"{path}:{lineno}: bad row (not UTF-8 text)")
                        continue
                    if not row:
                        continue
                    try:
                        parsed = parse(row)
                        if len(row) < ncols and lineno == lines.last_line and not _ends_line(fh):
                            raise ValueError(f"{len(row)} of {ncols} columns")
                    except (ValueError, IndexError) as e:
                        if not "".join(row).strip():
                            continue  # a blank row
                        bad_since = bad_since or lineno
                        why = "too few columns" if isinstance(e, IndexError) else (str(e) or "not understood")
                        if lineno == lines.last_line and not _ends_line(fh):
                            why += "; the file ends mid-row (export cut short?)"
                        self._bad(log, f"{path}:{lineno}: bad row {quote(','.join(row))} ({why})")
                        continue
                    if parsed is None:
                        continue
                    t, ch, b, flag = parsed
                    if offset:
                        t += offset
                    if bad_since is not None:
                        append((t, seq, None, bad_since, None, lineno))
                        seq += 1
                        bad_since = None
                    append((t, seq, ch, b, flag, lineno))
                    seq += 1
                    if seq >= next_yield:
                        yield out
                        out = []
                        append = out.append
                        next_yield = seq + BATCH
            except csv.Error as e:
                bad_since = bad_since or reader.line_num
                self._bad(log, f"{path}:{reader.line_num}: bad row ({e})")
                continue
            except OSError as e:
                log.add("read errors", f"{path}: read error after byte {lines.bytes_read}: {e.strerror or e}; "
                        "the rest of the file was not read")
                bad_since = bad_since or reader.line_num
            break
        if bad_since is not None:
            out.append((None, seq, None, bad_since, None, None))
        if out:
            yield out


def _ends_line(fh) -> bool:
    """Does the file end with a newline?  (Tells a row cut by a killed export from a bad one.)"""
    try:
        pos = fh.tell()
        fh.seek(-1, os.SEEK_END)
        last = fh.read(1)
        fh.seek(pos)
        return last in (b"\n", b"\r")
    except OSError:
        return True


def _items(batches: Iterator[list[tuple]]) -> Iterator[tuple]:
    """The rows of lists of rows, one by one."""
    for batch in batches:
        yield from batch


def _merge(batches: Iterator[list[tuple]], log: DamageLog, path: str) -> Iterator[list[tuple]]:
    """Rows in time order (stable: equal times keep file order) through a bounded window, as lists.

    The window is a sorted list: a row in order is appended, one out of order
    is inserted after the rows of its time.  A row earlier than one already
    yielded is replayed at that later time and reported.  A trailing marker
    (time None: bad rows at the very end) comes out last.
    """
    buf: list[tuple] = []
    head = 0  # buf[:head] were yielded
    last = None
    tail = None
    for batch in batches:
        if batch[-1][0] is not None:  # a list in time order, after everything held: appended whole
            times = [item[0] for item in batch]
            if (times[0] >= (buf[-1][0] if len(buf) > head else (last or 0)) and (last is None or times[0] >= last)
                    and times == sorted(times)):
                buf.extend(batch)
                n = len(buf) - head - REORDER_WINDOW
                if n > 0:
                    out = buf[head : head + n]
                    head += n
                    last = out[-1][0]
                    if head >= REORDER_WINDOW:
                        del buf[:head]
                        head = 0
                    yield out
                continue
        out: list[tuple] = []
        for item in batch:
            t = item[0]
            if t is None:
                tail = item
                break
            if last is not None and t < last:
                if item[2] is not None:
                    log.add("rows out of order",
                            f"{path}:{item[5]}: row at {t / 1e9:.9f} s comes after rows up to {last / 1e9:.9f} s "
                            f"(beyond the {REORDER_WINDOW}-row reorder window): replayed at {last / 1e9:.9f} s")
                t = last
                item = (last, -1, *item[2:])  # seq -1: replayed late (not a read sharing its time)
            if len(buf) == head or buf[-1][0] <= t:
                buf.append(item)
            else:
                insort_right(buf, item, head, key=_time)
            if len(buf) - head > REORDER_WINDOW:
                x = buf[head]
                head += 1
                last = x[0]
                out.append(x)
                if head >= REORDER_WINDOW:
                    del buf[:head]
                    head = 0
        if out:
            yield out
        if tail is not None:
            break
    rest = buf[head:]
    if tail is not None:
        rest.append(tail)
    if rest:
        yield rest


def _chunks(batches: Iterator[list[tuple]], per_read: bool, channels: set[str]) -> Iterator[Chunk | Gap]:
    """Merged rows (in lists) -> Chunks exactly as chunks_from_rows cuts a sorted list; a Gap where rows
    were skipped."""
    data = bytearray()
    times: list[int] = []
    flags: list[tuple[int, str]] = []
    run_t = 0
    run_ch: str | None = None
    last_t: int | None = None  # time of the last row before the current run
    hole: str | None = None  # rows were skipped before the current run
    hole_last: int | None = None

    def flush() -> Iterator[Chunk | Gap]:
        nonlocal hole
        c = Chunk(run_t, bytes(data), None if per_read else tuple(times), tuple(flags), run_ch or "")
        data.clear()
        times.clear()
        flags.clear()
        if hole is not None:
            yield gap_before(hole_last, c, hole)
            hole = None
        yield c

    for batch in batches:
        for t, _seq, ch, b, flag, lineno in batch:
            if ch is None:  # bad rows were skipped before this point
                if data:
                    last_t = run_t if per_read else times[-1]  # a read's rows share its time
                    yield from flush()
                if lineno is None:
                    where = f"line {b} to the end"
                else:
                    where = f"line {b}" if lineno - 1 <= b else f"lines {b}-{lineno - 1}"
                hole = hole or f"unreadable rows skipped ({where})"
                hole_last = last_t
                continue
            if data and (ch != run_ch or (t != run_t if per_read else len(data) >= PER_BYTE_CHUNK)):
                last_t = run_t if per_read else times[-1]  # a read's rows share its time
                yield from flush()
            if not data:
                run_t, run_ch = t, ch
                if ch not in channels and len(channels) < 256:
                    channels.add(ch)
            if flag:
                flags.append((len(data), flag))
            data.append(b)
            if not per_read:
                times.append(t)
    if data:
        yield from flush()
    elif hole is not None and last_t is not None:
        yield Gap(last_t, last_t, hole)


def chunks_from_rows(rows: list[Row]) -> tuple[str, list[Chunk]]:
    """A list of rows (already in time order) -> ("byte" | "read", Chunks); kept for small callers."""
    per_read = any(rows[i][0] == rows[i - 1][0] and rows[i][1] == rows[i - 1][1] for i in range(1, len(rows)))
    items = [(t, i, ch, b, flag, None) for i, (t, ch, b, flag) in enumerate(rows)]
    return ("read" if per_read else "byte"), list(_chunks([items], per_read, set()))
