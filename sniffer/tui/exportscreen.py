"""The export modal (`x`): what (the filtered view or the bookmarks), format (MCAP, pcap, CSV), file path.

The path starts as a free name next to the capture (export.default_path) and
follows the choices until the user edits it.  Enter in the path field exports;
a file that is there already is replaced only after a second Enter; a path
that cannot be written is one error line here, and the modal stays open.  The
writing runs on a worker thread (`start_export`), which ends with a
notification "N frames -> path".
"""

from __future__ import annotations

import threading
from typing import ClassVar

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Input, Label, RadioButton, RadioSet, Static

from sniffer.formats.outputs import OutputError, shown
from sniffer.tui.export import FORMATS, Export, default_path, existing, with_extension

FORMAT_LABELS = {"mcap": "MCAP", "pcap": "pcap", "csv": "CSV"}


class ExportScreen(ModalScreen["Export | None"]):
    """Dismissed with the opened Export, or None (Esc)."""

    BINDINGS: ClassVar[list[Binding]] = [Binding("escape", "dismiss(None)", "Cancel")]
    DEFAULT_CSS = """
    ExportScreen { align: center middle; }
    ExportScreen > Vertical { width: 90; height: auto; border: thick $primary; background: $surface; padding: 0 1; }
    ExportScreen Horizontal { height: auto; }
    ExportScreen Label { width: 8; padding: 1 0 0 0; }
    ExportScreen RadioSet { width: 1fr; layout: horizontal; }
    ExportScreen #export-error { color: $error; text-style: bold; height: auto; }
    ExportScreen #export-hint { color: $text-muted; }
    """

    def __init__(self, capture_path: str | None, view: int, bookmarks: int, *, inputs=()) -> None:
        super().__init__()
        self.capture_path = capture_path
        self.counts = {"view": view, "bookmarks": bookmarks}
        self.inputs = [p for p in inputs if p]
        self.what, self.fmt = "view", "mcap"
        self._auto = ""  # the path as this screen last proposed it (the user has not edited it since)
        self._confirm: str | None = None  # a path that exists and was asked about once

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Static("[b]Export[/b]")
            with Horizontal():
                yield Label("what")
                with RadioSet(id="export-what"):
                    yield RadioButton(f"the filtered view ({self.counts['view']} frames)", value=True)
                    yield RadioButton(f"the bookmarks ({self.counts['bookmarks']})")
            with Horizontal():
                yield Label("format")
                with RadioSet(id="export-format"):
                    for i, fmt in enumerate(FORMATS):
                        yield RadioButton(FORMAT_LABELS[fmt], value=i == 0)
            with Horizontal():
                yield Label("file")
                yield Input(id="export-path")
            yield Static("", id="export-error", markup=False)
            yield Static("Enter in the file field exports · Tab / arrows choose · Esc cancels", id="export-hint")

    def on_mount(self) -> None:
        self._propose()
        self.query_one("#export-path", Input).focus()

    def _propose(self) -> None:
        box = self.query_one("#export-path", Input)
        if box.value == self._auto:  # not edited: the default for the choices
            box.value = self._auto = default_path(self.capture_path, self.what, self.fmt)
        else:  # a name the user typed keeps its name, with this format's extension
            box.value = with_extension(box.value, self.fmt)

    def on_radio_set_changed(self, event: RadioSet.Changed) -> None:
        if event.radio_set.id == "export-what":
            self.what = ("view", "bookmarks")[event.index]
        else:
            self.fmt = list(FORMATS)[event.index]
        self._confirm = None
        self._propose()
        event.stop()

    def error(self, text: str) -> None:
        self.query_one("#export-error", Static).update(text)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        path = event.value.strip()
        if not self.counts[self.what]:
            self.error("no bookmarks to export (m marks a frame)" if self.what == "bookmarks"
                       else "the view is empty: nothing to export")
            return
        there = existing(self.fmt, path) if path else []
        if there and self._confirm != path:
            self._confirm = path
            self.error(f"{shown(', '.join(there), 150)} exists: Enter again replaces it (or change the name)")
            return
        try:
            job = Export(self.fmt, path, self.what, inputs=self.inputs)
        except OutputError as e:
            self._confirm = None
            self.error(str(e))
            return
        self.dismiss(job)


def start_export(app, job: Export) -> None:
    """Run an opened Export on a worker thread over a snapshot of the rows it names (the view as shown now,
    or every bookmark); progress goes to `app.export_status`, the end to a notification."""
    store = app.store
    rows = store.view if job.what == "view" else sorted(store.bookmarks)
    frames, n, info = store.blocks.reader(rows), len(rows), app.sink.info
    # quitting stops the export (its part files are removed); not the feed's stop, which a finished replay has set
    stop: threading.Event = app.quitting
    app.export_status = f"exporting 0/{n} -> {shown(job.path, 60)}"

    def progress(done: int) -> None:
        app.export_status = f"exporting {done}/{n} -> {shown(job.path, 60)}"

    def work() -> None:
        try:
            done = job.run(frames(), n, info, progress=progress, stop=stop)
        except Exception as e:  # noqa: BLE001 - one line for the user (a full disk, an I/O error)
            app.notify(f"export failed: {e}", severity="error", markup=False)
        else:
            if done >= 0:
                app.notify(job.describe(done), markup=False, timeout=8)
            else:
                app.notify(f"export stopped: nothing written to {shown(job.path, 60)}", severity="warning",
                           markup=False)
        finally:
            app.export_status = None

    app.run_worker(work, thread=True, group="export", exit_on_error=False)
