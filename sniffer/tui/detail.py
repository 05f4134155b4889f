"""Detail pane: the selected frame as a tree, a hex dump and its annotations in words.

Selecting a tree node (a point, a field or an annotation) highlights its
bytes in the hex dump: the spans the decoders recorded (a point's `span`, an
annotation's start..end), never guessed here.  Entering the tree puts its
cursor on the frame's first point (else its first annotation) and lights that
up: the tree is rebuilt for every frame, and a cursor left on the line it had
in the previous frame (often the last line: a PD-series answer has one point)
highlighted nothing and could not move on to anything that would.
"""

from __future__ import annotations

from time import monotonic

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.css.query import NoMatches
from textual.widgets import Static, Tree

from sniffer.frame import Frame
from sniffer.tui.timebase import TimeBase, delta_text

HL = "black on yellow"
FOLLOW_EVERY_S = 0.5  # while the list follows the tail, the detail is rebuilt at most this often


def hex_dump(raw: bytes, span: tuple[int, int] | None = None, width: int = 16) -> Text:
    text = Text()
    for off in range(0, len(raw), width):
        text.append(f"{off:04x}  ", "dim")
        chunk = raw[off:off + width]
        for i, b in enumerate(chunk):
            k = off + i
            style = HL if span and span[0] <= k < span[1] else None
            text.append(f"{b:02x}", style)
            text.append(" ", style if span and span[0] <= k < span[1] - 1 else None)
        text.append("   " * (width - len(chunk)) + " ")
        for i, b in enumerate(chunk):
            k = off + i
            style = HL if span and span[0] <= k < span[1] else "dim"
            text.append(chr(b) if 32 <= b < 127 else ".", style)
        text.append("\n")
    return text


def _span(span, size: int) -> tuple[int, int] | None:
    """A point's recorded span as the tree's node data (None if it has none or it does not fit the frame)."""
    if not span or len(span) != 2:
        return None
    s, e = span
    return (s, e) if 0 <= s < e <= size else None


def _fmt_value(p: dict) -> str:
    v = p.get("value")
    unit = p.get("unit")
    s = f"{v}" + (f" {unit}" if unit else "")
    if p.get("raw") is not None and p.get("raw") != v:
        s += f" (raw {p.get('raw')})"
    return s


class DetailPane(Vertical):
    DEFAULT_CSS = """
    DetailPane { height: 1fr; border-top: solid $primary; }
    DetailPane > Tree { height: 1fr; }
    DetailPane > #hex { height: auto; max-height: 10; padding: 0 1; }
    """

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.frame: Frame | None = None
        self.time = TimeBase()
        self.prev: tuple[int, int] | None = None
        self.span: tuple[int, int] | None = None
        self.due: tuple | None = None  # show()'s arguments for the tail's newest frame, at _shown_at + FOLLOW_EVERY_S
        self._shown_at = float("-inf")  # when a tail frame was last shown
        self._due_timer = None
        self._entry = None  # the node the cursor goes to when the tree is entered

    def compose(self) -> ComposeResult:
        tree: Tree = Tree("no frame selected", id="fields")
        tree.show_root = True
        yield tree
        yield Static("", id="hex")

    def on_mount(self) -> None:
        if self.frame is not None:  # selected before the tree was composed (a feed can be that quick)
            self.show(self.frame, self.time, self.prev)

    def show(self, f: Frame | None, time: TimeBase | None = None, prev: tuple[int, int] | None = None, *,
             following: bool = False) -> None:
        """Show a frame, its time in `time`'s base; `prev` is the previous shown frame's (t_ns, number) for Δt.

        `following`: f is the tail's newest frame (the list follows a capture), and the tail frame shown less
        than FOLLOW_EVERY_S ago stays until then (nobody reads a detail that changes 15 times a second;
        building it took a third of the TUI's time).  A frame the user selects shows at once.

        A tail frame that comes too soon is parked in `due` with one timer (`_show_due` shows the latest
        parked frame when it fires); any direct call drops what was parked.  Before the tree is composed
        only the frame is kept (on_mount shows it).  The tree is rebuilt from scratch: a root line
        (index, role, time, size, link, unit, function, model), the wire facts (protocol, time source,
        CRC, pair and latency, noise reason), the time in every base, the summary, the exception, the
        decoder's fields, one node per point and one leaf per annotation.  Every node that stands for
        bytes carries its span as `data`, as the decoders recorded it, so selecting it lights those bytes
        up in the hex dump; `_entry` is the first point (else annotation), where the cursor lands when
        the user enters the tree."""
        now = monotonic()
        if following:
            wait = self._shown_at + FOLLOW_EVERY_S - now
            if wait > 0:
                self.due = (f, time, prev)
                if self._due_timer is None:
                    self._due_timer = self.set_timer(wait, self._show_due)
                return
            self._shown_at = now
        else:
            self._shown_at = float("-inf")  # the next tail frame shows at once
        self.due = None
        if self._due_timer is not None:
            self._due_timer.stop()
            self._due_timer = None
        self.frame, self.span, self._entry = f, None, None
        self.time, self.prev = time or TimeBase(), prev
        try:
            tree = self.query_one("#fields", Tree)
        except NoMatches:
            return  # not composed yet: on_mount shows it
        tree.clear()
        if f is None:
            tree.root.set_label("no frame selected")
            self._hex()
            return
        head = f"#{f.index} {f.role} t={self.time.full_text(f.t_ns)} {len(f.raw)}B"
        if f.link:  # a capture of several links
            head += f" link {f.link}"
        if f.unit is not None:
            head += f" unit {f.unit}"
        if f.function is not None:
            head += f" fc{f.function:02X}"
        if f.model:
            head += f" model {f.model}"
        tree.root.set_label(head)
        tree.root.data = (0, len(f.raw))
        wire = tree.root.add("wire", expand=True, data=(0, len(f.raw)))
        wire.add_leaf(f"protocol: {f.protocol}  time source: {f.time_source}")
        if f.crc_ok is not None:
            crc = "ok" if f.crc_ok else f"BAD (expected {f.crc_expected:04x})" if f.crc_expected is not None else "BAD"
            wire.add_leaf(f"CRC: {crc}", data=(len(f.raw) - 2, len(f.raw)))
        if f.pair is not None:
            wire.add_leaf(f"pair: #{f.pair}" + (f"  latency {f.latency_ms:.2f} ms" if f.latency_ms is not None else ""))
        if f.noise_reason:
            wire.add_leaf(f"noise: {f.noise_reason}")
        self._add_time(tree.root, f)
        if f.summary:
            tree.root.add_leaf(f"summary: {f.summary}")
        if f.exception:
            tree.root.add_leaf(f"exception {f.exception.get('code')}: {f.exception.get('name')}",
                               data=(1, min(3, len(f.raw))))
        if f.fields:
            self._add_fields(tree.root.add("fields", expand=True), f.fields)
        if f.points:
            node = tree.root.add(f"points ({len(f.points)})", expand=True)
            for p in f.points:
                span = _span(p.get("span"), len(f.raw))
                addr = p.get("address")
                pid = f" {p['id']}" if p.get("id") else ""
                label = Text(f"{addr if addr is not None else '-'}{pid} {p.get('name', '')} = ")
                label.append(_fmt_value(p), "bold")
                pn = node.add(label, data=span, expand=False) if p.get("text") else node.add_leaf(label, data=span)
                self._entry = self._entry or pn
                if p.get("text"):
                    for part in str(p["text"]).split(", "):
                        pn.add_leaf(part, data=span)
        if f.annotations:
            node = tree.root.add(f"annotations ({len(f.annotations)})", expand=True)
            colour = {"error": "bold red", "warning": "yellow", "info": "dim"}
            for a in f.annotations:
                label = Text(f"{a.severity}: ", colour.get(a.severity))
                label.append(f"{a.code} — {a.detail} [bytes {a.start}..{a.end - 1}]")
                leaf = node.add_leaf(label, data=(a.start, a.end))
                self._entry = self._entry or leaf
        tree.root.expand()
        self._hex()

    def _show_due(self) -> None:
        self._due_timer = None
        if self.due is not None:
            self.show(*self.due, following=True)
    def _add_time(self, parent, f: Frame) -> None:
        """The frame's time in every base (collapsed: the root line has it in the one in use)."""
        node = parent.add("time", expand=False)
        for line in self.time.all_texts(f.t_ns):
            node.add_leaf(line)
        if self.prev is not None:
            node.add_leaf(f"Δt: {delta_text(f.t_ns - self.prev[0])} after #{self.prev[1]} (the previous frame shown)")

    def _add_fields(self, parent, fields) -> None:
        for item in fields:
            name, value, start, end, children = (list(item) + [None] * 5)[:5]
            label = f"{name}: {value}" if value is not None else f"{name}"
            if children:
                self._add_fields(parent.add(label, data=(start, end)), children)
            else:
                parent.add_leaf(label, data=(start, end))

    def _hex(self) -> None:
        raw = self.frame.raw if self.frame is not None else b""
        self.query_one("#hex", Static).update(hex_dump(raw, self.span))

    def _light(self, node) -> None:
        data = node.data
        self.span = data if isinstance(data, tuple) else None
        self._hex()

    def on_tree_node_highlighted(self, event: Tree.NodeHighlighted) -> None:
        self._light(event.node)

    def on_descendant_focus(self, event) -> None:
        tree = self.query_one("#fields", Tree)
        if event.widget is not tree or self._entry is None:
            return
        tree.last_line  # noqa: B018 - lays the lines out, so that the nodes know their line numbers
        tree.move_cursor(self._entry)
        self._light(self._entry)
