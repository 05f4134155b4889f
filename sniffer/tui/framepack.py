"""Frames kept compactly: sealed blocks of marshalled, zstd-compressed frames, rebuilt on demand.

A decoded Frame with its points, annotations and strings costs 1.5-3 kB as
Python objects; a million of them are gigabytes.  `FrameBlocks` keeps the
newest frames (fewer than `block`) as objects and seals every `block` of them
into one zstd-compressed block: each frame's own marshal dump behind a table of
where each ends (60-90 bytes a frame on drive traffic), beside a compressed
search text per block for the filter bar (filterlang.search_text).  A frame
asked for (a row on screen, the detail pane, a filter testing a value) is
rebuilt from its own dump alone; the rows on screen are kept in a small LRU
and the blocks decompressed in another.  One dump per frame, not one per block:
a filter that looks at every fourth frame unmarshals a quarter of the block,
and rebuilding a whole block is faster too (one big dump of 256 frames' points
took 5x as long to load as 256 small ones, measured on the stress and A510
scenarios).

What the list, the filters and navigation need for every row lives in the
store's `array` columns (model.py); this module holds the frames whole, plus
`RowIndex` (Frame.index -> row) and `FrameSeq` (`store.frames` as a sequence).
"""

from __future__ import annotations

import bisect
import itertools
import marshal
import operator
import pickle
from array import array
from collections import OrderedDict
from collections.abc import Callable, Iterator

import zstandard

from decoders.generic.block import RegisterBlock

from sniffer.codes import Annotation
from sniffer.filterlang import search_text
from sniffer.frame import Frame

BLOCK = 256  # frames per sealed block
FRAME_CACHE = 1024  # rebuilt frames kept (a screen is 40-100 rows)
BLOCK_CACHE = 8  # unpacked blocks kept
_LEVEL = 3  # zstd level: level 3 packs drive traffic about 12:1 in well under a microsecond a frame

# peer is None once a frame is decoded; encoded (the JSON the sinks wrote) can be made again;
# a decoder's compact block of points (decoders.generic.block) is kept as a tuple of its values
SLOTS = tuple(s for s in Frame.__slots__ if s not in ("peer", "encoded"))
_ANN = SLOTS.index("annotations")
_PTS = SLOTS.index("_points")
_get = operator.attrgetter(*SLOTS)
_SEP = "\x1e"  # between frames in a block's search text (record separator)
_PICKLED = 0x80  # a pickle (protocol >= 2) starts with 0x80; a marshal dump never does


def pack(f: Frame) -> tuple:
    """Every slot of a decoded frame but `peer`, as marshal can write it (annotations as plain tuples,
    a RegisterBlock as the tuple (space, address, values, offset): its point dicts are never built)."""
    t = _get(f)
    if t[_ANN]:
        t = (*t[:_ANN], [tuple(a) for a in t[_ANN]], *t[_ANN + 1:])
    pts = t[_PTS]
    if type(pts) is RegisterBlock:
        sh = pts.shape
        t = (*t[:_PTS], (sh.space, sh.addr, pts.values, sh.offset), *t[_PTS + 1:])
    return t


def unpack(t) -> Frame:
    f = Frame.__new__(Frame)
    for name, v in zip(SLOTS, t):
        setattr(f, name, v)
    f.annotations = [Annotation(*a) for a in t[_ANN]] if t[_ANN] else []
    pts = t[_PTS]
    if type(pts) is tuple:
        f._points = RegisterBlock(*pts)
    f.peer = None
    f.encoded = None
    return f


def _encode(s: str) -> bytes:
    return s.encode("utf-8", "surrogatepass")


def _dump(tuples: list[tuple]) -> bytes | None:
    """The frames' tuples marshalled one by one behind a table of where each ends (so one frame is
    read without the others: a filter looking at every fourth frame, a screen of rows), or None."""
    parts = []
    for t in tuples:
        try:
            parts.append(marshal.dumps(t))
        except ValueError:  # a value marshal cannot write (a decoder's own type in a point): pickle it
            try:
                parts.append(pickle.dumps(t, protocol=5))
            except Exception:  # noqa: BLE001 - not even that: the block keeps its frames as objects
                return None
    return array("I", itertools.accumulate(map(len, parts))).tobytes() + b"".join(parts)


def _load(data) -> tuple:
    return pickle.loads(data) if data[0] == _PICKLED else marshal.loads(data)


def _open_block(zd, packed: bytes, block: int) -> tuple[memoryview, array]:
    """A sealed block decompressed: its frames' bytes and where each ends (the block's head)."""
    data = memoryview(zd.decompress(packed))
    head = 4 * block
    ends = array("I")
    ends.frombytes(data[:head])
    return data[head:], ends


def _frame_in(opened: tuple[memoryview, array], i: int) -> Frame:
    data, ends = opened
    return unpack(_load(data[ends[i - 1] if i else 0:ends[i]]))


class FrameBlocks:
    """Frames by row (arrival order): `append`, `get(row)`, `search(block, needle)`."""

    def __init__(self, block: int = BLOCK, frame_cache: int = FRAME_CACHE, block_cache: int = BLOCK_CACHE) -> None:
        self.block = block
        self.tail: list[Frame] = []  # the newest frames, not sealed yet
        self.packed: list[bytes | list[Frame]] = []  # one per sealed block (its frames if they would not pack)
        self.texts: list[bytes] = []  # its search text
        self.packed_bytes = 0
        self._frame_cache: OrderedDict[int, Frame] = OrderedDict()
        self._frame_cache_size = frame_cache
        self._block_cache: OrderedDict[int, tuple[memoryview, array]] = OrderedDict()  # unpacked, with its ends
        self._block_cache_size = block_cache
        self._zc = zstandard.ZstdCompressor(level=_LEVEL)
        self._zd = zstandard.ZstdDecompressor()

    def __len__(self) -> int:
        return len(self.packed) * self.block + len(self.tail)

    @property
    def sealed_rows(self) -> int:
        """Rows below this are in sealed blocks; the rest are `tail` objects."""
        return len(self.packed) * self.block

    def append(self, f: Frame) -> None:
        self.tail.append(f)
        if len(self.tail) >= self.block:
            self._seal()

    def _seal(self) -> None:
        frames, self.tail = self.tail, []
        base = self.sealed_rows
        dump = _dump([pack(f) for f in frames])
        data = frames if dump is None else self._compress(dump)
        text = self._compress(_encode(_SEP.join([search_text(f) for f in frames])))
        self.packed.append(data)
        self.texts.append(text)
        self.packed_bytes += (0 if dump is None else len(data)) + len(text)
        # the frames just sealed are the ones most likely on screen: keep them as they are
        c = self._frame_cache
        c.update(zip(range(base, base + len(frames)), frames))
        while len(c) > self._frame_cache_size:
            c.popitem(last=False)

    def _compress(self, data: bytes) -> bytes:
        # zstandard returns a bytes object as large as its worst-case bound (uncompressed size and
        # more) with a shorter length: copied, a block holds 10 kB instead of 80
        return bytes(memoryview(self._zc.compress(data)))

    def _remember(self, row: int, f: Frame) -> None:
        c = self._frame_cache
        c[row] = f
        if len(c) > self._frame_cache_size:
            c.popitem(last=False)

    def _unpacked(self, b: int, i: int) -> Frame:
        """Frame i of sealed block b, rebuilt (the block stays decompressed in a small LRU)."""
        c = self._block_cache
        got = c.get(b)
        if got is None:
            got = c[b] = _open_block(self._zd, self.packed[b], self.block)
            if len(c) > self._block_cache_size:
                c.popitem(last=False)
        else:
            c.move_to_end(b)
        return _frame_in(got, i)

    def get(self, row: int) -> Frame:
        sealed = self.sealed_rows
        if row < 0:
            row += len(self)
        if row >= sealed:
            return self.tail[row - sealed]
        if row < 0:
            raise IndexError(row)
        c = self._frame_cache
        f = c.get(row)
        if f is not None:
            c.move_to_end(row)
            return f
        b, i = divmod(row, self.block)
        data = self.packed[b]
        if type(data) is list:
            return data[i]
        f = self._unpacked(b, i)
        self._remember(row, f)
        return f

    def peek(self, row: int) -> Frame:
        """The frame at a row, as `get`, but not remembered: a filter looking at many rows does not push
        the rows on screen out of the cache."""
        sealed = self.sealed_rows
        if row >= sealed:
            return self.tail[row - sealed]
        f = self._frame_cache.get(row)
        if f is not None:
            return f
        b, i = divmod(row, self.block)
        data = self.packed[b]
        return data[i] if type(data) is list else self._unpacked(b, i)

    def search(self, b: int, needle: bytes) -> list[int]:
        """Offsets (within sealed block b) of the frames whose search text contains needle (UTF-8)."""
        text = self._zd.decompress(self.texts[b])
        if needle not in text:
            return []
        parts = text.split(_SEP.encode())
        if len(parts) != self.block:  # a separator inside a summary: ask the frames themselves
            s = needle.decode("utf-8", "surrogatepass")
            return [i for i in range(self.block) if s in search_text(self.get(b * self.block + i))]
        return [i for i, p in enumerate(parts) if needle in p]

    def clear_cache(self) -> None:
        self._frame_cache.clear()
        self._block_cache.clear()

    def reader(self, rows) -> Callable[[], Iterator[Frame]]:
        """The frames of `rows` (ascending), to be read on another thread (an export): what they need is
        taken now (sealed blocks are never changed, the unsealed tail is copied); the reading uses its own
        decompressor and none of the caches the UI thread uses."""
        rows = array("q", rows)
        packed, sealed, tail, size = self.packed, self.sealed_rows, list(self.tail), self.block

        def frames() -> Iterator[Frame]:
            zd = zstandard.ZstdDecompressor()
            cur, opened = -1, None
            for r in rows:
                if r >= sealed:
                    yield tail[r - sealed]
                    continue
                b, i = divmod(r, size)
                data = packed[b]
                if type(data) is list:  # a block that would not pack keeps its frames
                    yield data[i]
                    continue
                if b != cur:
                    cur, opened = b, _open_block(zd, data, size)
                yield _frame_in(opened, i)

        return frames


class RowIndex:
    """Frame.index -> row.  The pipeline numbers frames in arrival order, so a sorted array and
    bisect do (8 bytes a row, not a dict's ~100); the odd frame out of order goes in a dict."""

    def __init__(self) -> None:
        self.keys = array("q")
        self.rows: array | None = None  # only once rows and key positions part
        self.extra: dict[int, int] = {}

    def add(self, index: int, row: int) -> None:
        k = self.keys
        if k and index <= k[-1]:
            self.extra[index] = row
            return
        if self.rows is None and row != len(k):
            self.rows = array("q", range(len(k)))
        k.append(index)
        if self.rows is not None:
            self.rows.append(row)

    def get(self, index: int, default=None):
        r = self.extra.get(index)
        if r is not None:
            return r
        k = self.keys
        i = bisect.bisect_left(k, index)
        if i < len(k) and k[i] == index:
            return i if self.rows is None else self.rows[i]
        return default

    def __getitem__(self, index: int) -> int:
        r = self.get(index)
        if r is None:
            raise KeyError(index)
        return r

    def __contains__(self, index: int) -> bool:
        return self.get(index) is not None


class FrameSeq:
    """`store.frames`: the frames as a read-only sequence (each item rebuilt or cached on demand)."""

    def __init__(self, blocks: FrameBlocks) -> None:
        self._blocks = blocks

    def __len__(self) -> int:
        return len(self._blocks)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self._blocks.get(r) for r in range(*i.indices(len(self._blocks)))]
        if not -len(self._blocks) <= i < len(self._blocks):
            raise IndexError(i)
        return self._blocks.get(i)

    def __iter__(self):
        get = self._blocks.get
        return (get(r) for r in range(len(self._blocks)))
