"""The key bar: Textual's Footer, rebuilt only when the keys it shows change.

Textual's Footer removes and mounts all its keys again whenever the screen's bindings may have
changed, which is at every focus change: a tab switch (`1`, `2`, ...) moves the focus, so each one
rebuilt some twenty FooterKey widgets and styled them anew. Under a live stress capture in the
browser view that was a large share of the viewer's CPU while keys were pressed (profiled with
py-spy), for a bar that looked the same before and after.
"""

from __future__ import annotations

from textual.screen import Screen
from textual.widgets import Footer


def shown_keys(screen: Screen) -> tuple:
    """What the footer draws from the screen's active bindings: key, label, action, enabled, tooltip."""
    return tuple((b.key, b.key_display, b.description, b.action, enabled, tooltip, b.group)
                 for _node, b, enabled, tooltip in screen.active_bindings.values() if b.show)


class KeyBar(Footer):
    """A Footer that recomposes only when the keys it would show differ from those it shows."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._shown: tuple | None = None
        self.rebuilds = 0  # how many times the keys were mounted anew (tests)

    def bindings_changed(self, screen: Screen) -> None:
        self._bindings_ready = True
        if not screen.app.app_focus or not self.is_attached or screen is not self.screen:
            return
        keys = shown_keys(screen)
        if keys == self._shown:
            return
        self._shown = keys
        self.rebuilds += 1
        self.call_after_refresh(self.recompose)
