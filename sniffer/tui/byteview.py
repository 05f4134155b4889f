"""The byte view (tab 6): the bytes as the port delivered them, one read per line, for framing problems.

Each read (sniffer.analysis.reads.Read, kept in a ReadRing) shows its time, the gap
since the previous read in ms and in character times at the line's baud (with
several links, the previous read of its own link, at that link's baud), its
length and its bytes; a read longer than a line goes on below.  A `│` before
a byte marks where a frame begins, the bytes take their frame's colour (the
frame list's: request, response, error, exception, noise ...), the frames
they went to are listed after them, and the selected frame's bytes are
highlighted.  The gap: per read (a USB adapter), from the previous read's
return to this one's; per byte (a logic analyzer), the silence from the end
of the previous read's last byte to this read's first.  Where reads never
came (a viewer that fell behind has reads dropped) the gap says how many
bytes are missing ("34B lost") instead of a time.  A read the live reader made
after it stalled (its CPU or the interpreter taken for more than 20 ms:
Chunk.unseen_ns) says `stall` in the chars column: its bytes came at some time
within the stall, so its gap is not a silence the line kept.

Keys: ↑ ↓ PgUp PgDn Home End/G move between reads (End follows the newest);
← → the previous / next frame; Enter goes to the selected frame in the
Frames tab.  Only the lines on screen are drawn (Line API, as the frame list).
"""

from __future__ import annotations

import bisect
from array import array
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.geometry import Size
from textual.message import Message
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widgets import Static

from sniffer.line import LineSettings
from sniffer.analysis.reads import RING_READS, Read
from sniffer.tui.framelist import S_CURSOR, S_REQ, S_RSP, row_style
from sniffer.tui.store import ROLES, FrameStore
from sniffer.tui.readring import ReadRing
from sniffer.tui.vlist import MOVE_KEYS

PREFIX = 42  # "   time  gap  chars  len  " before the bytes
LINK_LOOKBACK = 64  # reads looked back for the last one of the same link (the gap column, several links)
S_SELECTED = Style(color="black", bgcolor="yellow", bold=True)
S_BEGIN = Style(color="bright_white", bold=True)
S_STALL = Style(color="black", bgcolor="dark_orange", bold=True)


def _char_ns(baud, parity, stopbits, databits) -> int | None:
    if not baud:
        return None
    try:
        return LineSettings(int(baud), parity or "N", stopbits or 1, databits or 8).char_ns
    except (ValueError, TypeError):
        return None


def char_ns(info) -> int | None:
    """One character's time on the line of a CaptureInfo, or None (no baud known)."""
    if info is None:
        return None
    return _char_ns(info.baud, info.parity, info.stopbits, info.databits)


def link_char_ns(info) -> dict[str, int | None]:
    """One character's time on each line of a CaptureInfo, by link name ("": the capture's one line)."""
    out = {"": char_ns(info)}
    for x in (info.links if info is not None else ()):
        out[str(x.get("name", ""))] = _char_ns(x.get("baud"), x.get("parity"), x.get("stopbits"), x.get("databits"))
    return out


def header(bpl: int) -> str:
    """The column names above reads of `bpl` bytes a line."""
    return (f"   {'time (s)':>12} {'gap':>10} {'chars':>8} {'len':>4}  "
            f"{'bytes (│ a frame begins; colour: its frame)':<{3 * bpl + 2}}→ the frames they went to")


def bytes_per_line(width: int) -> int:
    return max(8, min(32, (width - PREFIX - 30) // 3))


class ByteView(ScrollView, can_focus=True):
    """Lines are reads of the ring (a long read takes several); `cursor` is a read's seq."""

    BINDINGS: ClassVar[list[Binding]] = [
        *MOVE_KEYS,
        Binding("left", "step_frame(0)", "Prev frame", show=False),
        Binding("right", "step_frame(1)", "Next frame", show=False),
        Binding("enter", "choose", "Go to frame", show=False),
    ]
    DEFAULT_CSS = "ByteView { height: 1fr; }"

    class Chosen(Message):
        """Enter: go to this frame in the Frames tab."""

        def __init__(self, index: int) -> None:
            self.index = index
            super().__init__()

    class Moved(Message):
        """The cursor, the selected frame or the reads changed (the pane's note line follows)."""

    def __init__(self, ring: ReadRing, store: FrameStore, **kw) -> None:
        super().__init__(**kw)
        self.ring = ring
        self.store = store
        self.char_ns: dict[str, int | None] = {}  # by link (link_char_ns)
        self.cursor = -1  # seq of the read under the cursor
        self.frame: int | None = None  # the selected frame's index
        self.follow = True
        self._line_of = array("q")  # first line of each read in the ring
        self._layout = (-1, 0)  # (ring.first_seq, bytes per line) _line_of was built for
        self._lines = 0

    # ---- layout
    def _relayout(self) -> None:
        ring, bpl = self.ring, bytes_per_line(self.size.width or 140)
        if self._layout != (ring.first_seq, bpl):
            self._layout = (ring.first_seq, bpl)
            self._line_of = array("q")
            self._lines = 0
        line_of, n = self._line_of, self._lines
        for r in ring.reads[len(line_of):]:
            line_of.append(n)
            n += max(1, -(-len(r.data) // bpl))
        self._lines = n
        self.virtual_size = Size(max(self.size.width, PREFIX + 3 * bpl + 30), n)

    def refresh_reads(self) -> None:
        """After reads were added to the ring (or the size changed)."""
        self._relayout()
        ring = self.ring
        if self.follow and len(ring):
            self._set_cursor(ring.end_seq - 1, select=True)
            self.scroll_end(animate=False, immediate=True)
        elif self.cursor < ring.first_seq and len(ring):
            self.cursor = ring.first_seq  # its read was dropped from the ring
        self.refresh()
        self.post_message(self.Moved())

    def on_resize(self, event) -> None:
        self.refresh_reads()
        if not self.follow:
            self._bring_into_view(self.cursor)

    def note(self) -> str:
        """One line for above the view: what the ring holds, where the selected frame is."""
        ring = self.ring
        if not len(ring):
            return "no reads yet (a capture from an older sniffer sends none)"
        text = (f"{len(ring)} reads, {ring.size} bytes kept (the last {RING_READS} at most; "
                f"read {ring.first_seq}..{ring.end_seq - 1})")
        if self.frame is not None:
            seq = ring.find(self.frame)
            text += (f"   frame #{self.frame}: read {seq}" if seq is not None
                     else f"   frame #{self.frame}: its bytes are older than the reads kept")
        return text

    # ---- selection
    def _set_cursor(self, seq: int, *, select: bool) -> None:
        ring = self.ring
        r = ring.get(seq)
        if r is None:
            return
        self.cursor = seq
        if select and r.marks:  # the first frame that begins in the read (or the one it continues)
            begins = [i for p, i in r.marks if p or not r.cont]
            self.frame = begins[0] if begins else r.marks[0][1]
        self._bring_into_view(seq)
        self.refresh()
        self.post_message(self.Moved())

    def _bring_into_view(self, seq: int) -> None:
        i = seq - self.ring.first_seq
        if not 0 <= i < len(self._line_of):
            return
        first = self._line_of[i]
        last = (self._line_of[i + 1] if i + 1 < len(self._line_of) else self._lines) - 1
        top, h = round(self.scroll_offset.y), max(self.scrollable_content_region.height, 1)
        if first < top:
            self.scroll_to(y=first, animate=False, immediate=True)
        elif last >= top + h:
            self.scroll_to(y=max(first, last - h + 1), animate=False, immediate=True)

    def show_frame(self, index: int | None) -> bool:
        """Select frame `index` and bring its first byte's read into view; False if its bytes are not kept."""
        self.frame = index
        seq = None if index is None else self.ring.find(index)
        if seq is None:
            self.refresh()
            self.post_message(self.Moved())
            return False
        self.follow = False
        self._relayout()
        self._set_cursor(seq, select=False)
        return True

    # ---- actions
    def _move_to(self, seq: int) -> None:
        ring = self.ring
        if not len(ring):
            return
        seq = max(ring.first_seq, min(ring.end_seq - 1, seq))
        self.follow = seq == ring.end_seq - 1
        self._set_cursor(seq, select=True)

    def action_cursor(self, delta: int) -> None:
        self._move_to(self.cursor + delta)

    def action_page(self, direction: int) -> None:
        self._move_to(self.cursor + direction * max(self.scrollable_content_region.height - 1, 1))

    def action_first(self) -> None:
        self._move_to(self.ring.first_seq)

    def action_last(self) -> None:
        self._move_to(self.ring.end_seq - 1)
        self.follow = True

    def action_step_frame(self, forward: int) -> None:
        if self.frame is None:
            return
        index = self.ring.frames_between(self.cursor, self.frame, bool(forward))
        if index is not None:
            self.follow = False
            self.show_frame(index)

    def action_choose(self) -> None:
        if self.frame is not None:
            self.post_message(self.Chosen(self.frame))

    def on_click(self, event) -> None:
        line = round(self.scroll_offset.y) + event.y
        i = bisect.bisect_right(self._line_of, line) - 1
        if 0 <= i < len(self.ring) and line < self._lines:
            self._move_to(self.ring.first_seq + i)

    # ---- drawing
    def _gap(self, seq: int, r: Read) -> tuple[str, str]:
        prev = self.ring.get(seq - 1)
        if prev is None:
            return "", ""
        if prev.offset + len(prev.data) != r.offset:  # reads between them never came (a viewer fell behind)
            return f"{r.offset - prev.offset - len(prev.data)}B lost", ""
        back = 1
        while prev.link != r.link and back < LINK_LOOKBACK:  # several links: the silence on this read's own
            back += 1
            prev = self.ring.get(seq - back)
            if prev is None:
                return "", ""
        if prev.link != r.link:
            return "", ""
        ch = self.char_ns.get(r.link)
        if r.last_ns is not None and prev.last_ns is not None:  # per byte: silence between the two
            gap = r.t_ns - prev.last_ns - (ch or 0)
        else:
            gap = r.t_ns - prev.t_ns
        return f"{gap / 1e6:8.3f}ms", f"{gap / ch:6.1f}ch" if ch else ""

    def _frame_style(self, index: int) -> Style | None:
        if index == self.frame:
            return S_SELECTED
        row = self.store.row_of.get(index)
        if row is None:
            return None
        st = row_style(self.store.flags[row])
        if st is not None:
            return st
        role = self.store.role[row]
        role = ROLES[role] if role < len(ROLES) else ""
        return S_REQ if role == "request" else S_RSP if role == "response" else None

    def format_line(self, seq: int, part: int, bpl: int) -> Text:
        """Line `part` of read `seq`: the read's columns on its first line, bytes from part * bpl."""
        r = self.ring.get(seq)
        text = Text(no_wrap=True, overflow="crop")
        if part == 0:
            gap, chars = self._gap(seq, r)
            text.append(f"   {(r.t_ns - self.store.t0_ns) / 1e9:12.6f} {gap:>10} ")
            if r.unseen_ns is not None:  # the reader stalled: the gap is not the line's silence
                text.append(f"{'stall':>8}", S_STALL)
            else:
                text.append(f"{chars:>8}")
            text.append(f" {len(r.data):4d}  ")
        else:
            text.append(" " * PREFIX)
        begins = r.starts()
        lo = part * bpl
        styles: dict[int, Style | None] = {}
        for k in range(lo, min(lo + bpl, len(r.data))):
            index = r.frame_at(k)
            st = styles.get(index) if index in styles else styles.setdefault(index, self._frame_style(index))
            text.append("│" if k in begins else " ", S_BEGIN if k in begins else st if k > lo else None)
            text.append(f"{r.data[k]:02x}", st)
        if part == 0:
            text.append(" " * (3 * (bpl - min(bpl, len(r.data))) + 2))
            text.append("→ " + (f"{r.link} " if r.link else "") + " ".join(f"#{i}" for i in r.frames), "dim")
        if seq == self.cursor:
            text.stylize_before(S_CURSOR)
        return text

    def render_line(self, y: int) -> Strip:
        scroll_x, scroll_y = self.scroll_offset
        line = scroll_y + y
        width = self.scrollable_content_region.width
        i = bisect.bisect_right(self._line_of, line) - 1
        if i < 0 or line >= self._lines or i >= len(self.ring):
            return Strip.blank(width, self.rich_style)
        bpl = self._layout[1]
        text = self.format_line(self.ring.first_seq + i, line - self._line_of[i], bpl)
        text.stylize_before(self.rich_style)
        segments = [s for s in text.render(self.app.console) if s.text != "\n"]
        return Strip(segments).crop_extend(scroll_x, scroll_x + width, self.rich_style)


class BytesPane(Vertical):
    """The tab: a note (what the ring holds, where the selected frame is), the column header, the view."""

    DEFAULT_CSS = """
    BytesPane { height: 1fr; }
    BytesPane > #bytesnote { height: 1; color: $text-muted; }
    BytesPane > #byteshead { height: 1; color: $text-muted; text-style: bold; }
    """

    def __init__(self, ring: ReadRing, store: FrameStore, **kw) -> None:
        super().__init__(**kw)
        self.ring, self.store = ring, store

    def compose(self) -> ComposeResult:
        yield Static("", id="bytesnote", markup=False)
        yield Static(header(bytes_per_line(140)), id="byteshead", markup=False)
        yield ByteView(self.ring, self.store, id="byteview")

    def on_byte_view_moved(self, message: ByteView.Moved) -> None:
        message.stop()
        view = self.query_one(ByteView)
        self.query_one("#bytesnote", Static).update(view.note())
        self.query_one("#byteshead", Static).update(header(view._layout[1] or bytes_per_line(view.size.width)))
