"""The Verdicts tab: `sniffer diagnose`'s findings on what the view holds so far, most severe first.

The findings come from the FrameStore's diagnosis engine (sniffer.diagnose, fed as frames come in, also from
a live capture); the App asks for them while the tab is shown.  A list of the findings (severity, kind,
where, the sentence), the highlighted one's evidence, frames and what to do below it; Enter (or a click on
the highlighted line) goes to its first frame in the Frames tab.
"""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical, VerticalScroll
from textual.widgets import OptionList, Static
from textual.widgets.option_list import Option

from sniffer.tui.plot import JumpToFrame

STYLE = {"error": "bold bright_red", "warning": "bold dark_orange", "info": "bold grey62"}


def _line(f) -> Text:
    span = "" if f.t_start is None else f"  {f.t_start:.1f}-{f.t_end:.1f} s"
    t = Text(f"{f.severity.upper():<8}", style=STYLE.get(f.severity, ""), no_wrap=True)
    t.append(f"{f.kind}  ", style="bold")
    t.append(f"{f.where}{span}\n")
    t.append(f"  {f.text}", style="default")
    return t


def detail_text(f) -> Text:
    from sniffer.diagnose.finding import fmt_value

    t = Text()
    when = f.when() if hasattr(f, "when") else ""
    if when:
        t.append("when: ", style="bold")
        t.append(f"{when}\n")
    for k, v in f.evidence.items():
        t.append(f"{k.replace('_', ' ')}: ", style="bold")
        t.append(f"{fmt_value(v)}\n")
    if f.statistic:
        t.append("statistic: ", style="bold")
        t.append(", ".join(f"{k} {fmt_value(v)}" for k, v in f.statistic.items()) + "\n")
    if f.frames:
        t.append("frames: ", style="bold")
        t.append(" ".join(f"#{i}" for i in f.frames) + "   (Enter goes to the first)\n")
    t.append("do: ", style="bold")
    t.append(f.action)
    return t


class VerdictsPane(Vertical):
    DEFAULT_CSS = """
    VerdictsPane { height: 1fr; }
    VerdictsPane OptionList { height: 2fr; }
    VerdictsPane #verdict-detail { height: 1fr; border-top: solid $panel; padding: 0 1; }
    """
    BINDINGS: ClassVar[list[Binding]] = []

    def __init__(self, **kw) -> None:
        super().__init__(**kw)
        self.findings: list = []
        self._shown: list[tuple] | None = None

    def compose(self) -> ComposeResult:
        yield OptionList(id="verdict-list")
        with VerticalScroll(id="verdict-detail"):
            yield Static("", id="verdict-text")

    @property
    def list(self) -> OptionList:
        return self.query_one("#verdict-list", OptionList)

    def update_findings(self, findings: list) -> None:
        """Show these findings (the list is rebuilt only when they changed; the highlight stays put)."""
        key = [(f.severity, f.kind, f.link, f.unit, f.text) for f in findings]
        if key == self._shown:
            return
        self._shown = key
        self.findings = list(findings)
        ol = self.list
        keep = ol.highlighted
        ol.clear_options()
        if not findings:
            ol.add_option(Option(Text("No finding yet: nothing on the line looks wrong.", style="grey62"),
                                 disabled=True))
            self._detail(None)
            return
        ol.add_options([Option(_line(f), id=str(i)) for i, f in enumerate(findings)])
        ol.highlighted = min(keep or 0, len(findings) - 1)
        self._detail(self.findings[ol.highlighted])

    def _detail(self, f) -> None:
        self.query_one("#verdict-text", Static).update(detail_text(f) if f is not None else "")

    def on_option_list_option_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        if event.option_index is not None and event.option_index < len(self.findings):
            self._detail(self.findings[event.option_index])

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        event.stop()
        if event.option_index < len(self.findings) and self.findings[event.option_index].frames:
            self.post_message(JumpToFrame(self.findings[event.option_index].frames[0]))
