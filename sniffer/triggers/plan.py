"""When trigger windows open, grow and close: sans-I/O, on capture time only (tested with synthetic times).

A rule *matches* a frame; a match *fires* when its rule is armed.  A rule is armed at the start and
again once it has gone `quiet_ns` (the post span, at least 1 s) without a match, so a drive that
reports its fault in every poll for an hour fires once, not on every poll.

    fire, no window open   -> a window opens: start = t - pre, end = t + post
    match in a window      -> the window's end moves to t + post (a rule that fires there is
                              recorded beside the first: "extend the open window, record both rules")
    end reaches the cap    -> no further: a window spans at most max_window after its first trigger;
                              matches past it fire only once their rule re-armed (quiet for post)
    capture time > end     -> the window takes no more raw events; frames up to `end` still arrive
                              (the pairer settles a request only when its answer or timeout comes)
    capture time > end + settle -> the window is complete (`advance` returns it)

A match whose window has closed but whose rule is not armed is `suppressed` (counted, no window).
"""

from __future__ import annotations

from dataclasses import dataclass, field

MIN_QUIET_NS = 1_000_000_000


@dataclass
class Firing:
    """One trigger event: a rule that fired on a frame."""

    rule: int
    t_ns: int
    detail: dict = field(default_factory=dict)  # what the sink knows of the frame (index, summary, ...)


@dataclass
class Window:
    n: int
    trigger_ns: int  # the first firing's frame time
    start_ns: int  # trigger - pre: the span asked for
    end_ns: int  # last match + post (capped)
    cap_ns: int  # trigger + max_window: end never goes past it
    firings: list[Firing]
    matches: dict[int, int]  # rule -> frames that matched it in the window
    capped: bool = False
    complete: bool = False  # capture time passed end + settle (False: the capture ended first)

    def holds(self, t_ns: int) -> bool:
        return self.start_ns <= t_ns <= self.end_ns

    @property
    def rules(self) -> list[int]:
        """The rules that fired in it, first firing first (each once)."""
        return list(dict.fromkeys(f.rule for f in self.firings))


class Plan:
    def __init__(self, rules: int, pre_ns: int, post_ns: int, *, max_window_ns: int | None = None,
                 settle_ns: int = 2_000_000_000, quiet_ns: int | None = None) -> None:
        self.pre_ns = pre_ns
        self.post_ns = post_ns
        self.max_window_ns = max(post_ns, max_window_ns if max_window_ns is not None else 10 * post_ns)
        self.settle_ns = settle_ns
        self.quiet_ns = max(MIN_QUIET_NS, post_ns) if quiet_ns is None else quiet_ns
        self.last_match: list[int | None] = [None] * rules
        self.active: list[Window] = []  # oldest first; at most one takes new matches
        self.now_ns: int | None = None
        self.windows = 0
        self.fired = 0
        self.suppressed = 0

    def armed(self, rule: int, t_ns: int) -> bool:
        last = self.last_match[rule]
        return last is None or t_ns - last > self.quiet_ns

    def match(self, rule: int, t_ns: int, detail: dict | None = None) -> tuple[Window | None, Firing | None]:
        """A frame at t_ns matched `rule`: (the window it went into or opened, the firing or None)."""
        fires = self.armed(rule, t_ns)
        last = self.last_match[rule]
        self.last_match[rule] = t_ns if last is None else max(last, t_ns)
        w = next((w for w in reversed(self.active) if w.holds(t_ns)), None)
        if w is None and not fires:
            self.suppressed += 1
            return None, None
        firing = Firing(rule, t_ns, detail or {}) if fires else None
        if w is None:
            self.windows += 1
            cap = t_ns + self.max_window_ns
            w = Window(self.windows, t_ns, t_ns - self.pre_ns, min(t_ns + self.post_ns, cap), cap, [], {})
            self.active.append(w)
        else:
            end = t_ns + self.post_ns
            if end > w.cap_ns:
                end, w.capped = w.cap_ns, True
            if end > w.end_ns and (self.now_ns is None or self.now_ns <= w.end_ns):
                w.end_ns = end  # a window that took its last raw event already stays as it is
        w.matches[rule] = w.matches.get(rule, 0) + 1
        if firing is not None:
            w.firings.append(firing)
            self.fired += 1
        return w, firing

    def advance(self, now_ns: int) -> list[Window]:
        """Capture time is now_ns: the windows complete by now (removed from `active`)."""
        if self.now_ns is None or now_ns > self.now_ns:
            self.now_ns = now_ns
        done = [w for w in self.active if self.now_ns > w.end_ns + self.settle_ns]
        for w in done:
            w.complete = True
            self.active.remove(w)
        return done

    def takes_raw(self, w: Window, t_ns: int) -> bool:
        return w.start_ns <= t_ns <= w.end_ns

    def finish(self) -> list[Window]:
        """The capture ended: every window still open, as it is (complete if its post span had passed)."""
        done, self.active = self.active, []
        for w in done:
            w.complete = self.now_ns is not None and self.now_ns > w.end_ns
        return done


__all__ = ["Firing", "Plan", "Window"]
