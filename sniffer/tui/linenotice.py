"""The TUI's side of the line-settings warning: the frames it takes in judged (sniffer.analysis.linehealth).

The App hands every batch it takes into its store to `LineNotice.take`; a line that breaks gives the
warning's text once (the App shows it as a notification) and a mark in the status bar while it stays
broken.  The App judges what it shows whatever feeds it (a replay, a capture on this machine, an
attached viewer), so a capture process's own stderr warning (`is_line_warning`) is not shown twice.
"""

from __future__ import annotations

from sniffer.analysis.linehealth import LineWatch, line_settings, warning_text
from sniffer.detect.hint import what_to_do


class LineNotice:
    def __init__(self, file: str | None = None) -> None:
        self.file = file  # the capture a replay reads (None: a line read now)
        self.watch = LineWatch()
        self.broken: list[str] = []  # links broken now, in the order they broke ("" for a capture of one line)

    def take(self, frames, info) -> list[str]:
        """Judge a batch of frames; the warnings to show (one per line that broke)."""
        said = []
        frame = self.watch.frame
        for f in frames:
            change = frame(f)
            if change is None:
                continue
            link = change.link
            if change.broken:
                self.broken.append(link)
                said.append(warning_text(change, line_settings(info, link), what_to_do(info, link, file=self.file)))
            elif link in self.broken:
                self.broken.remove(link)
        return said

    def mark(self) -> str:
        """The status bar's mark: '' while every line looks right."""
        if not self.broken:
            return ""
        links = ", ".join(x for x in self.broken if x)
        return f"  [{'link ' + links + ': ' if links else ''}most frames bad: line settings?]"
