"""The trigger sink: rules over every frame, a ring of the last minutes, a window file per trigger event.

    sink = TriggerSink(spec, folder, stem, ids=register_ids(registry), char_ns=line.char_ns)

The session adds it when the capture has `--trigger` (Session.open), binds `settled` to its
pipeline's and calls `advance(t)` with every source event's time (a quiet line still closes
its windows).  Each raw event and frame goes into the ring (ring.py) and into the windows that
hold its time; each frame is tested against every rule (one filterlang Query each, so `rate()`
counts every frame); plan.py says when a window opens, grows and is complete.  A window's raw
events start at an event before which the framer had nothing pending (its replay frames as
the capture did) at or up to ALIGN_NS before `t - pre`, else at the first one after.  Its
metadata holds what the decoders knew at that start (`decoder_state`, decoders/carry.py: the
sink keeps each change with its time, the session binds `decoder_state` and `state_version`
to its pipeline's), so the window replayed alone scales and names its values as the capture did.
"""

from __future__ import annotations

import os
import time

from decoders.carry import KEY

from sniffer.events import Chunk, Gap
from sniffer.filterlang import Context, Query
from sniffer.analysis.flags import frame_flags
from sniffer.formats.mcap.format import decode_event, encode_event
from sniffer.formats.records import frame_json, loads
from sniffer.sinks.base import Sink
from sniffer.formats.text import frame_line
from sniffer.stderr import say
from sniffer.triggers.command import CommandRunner
from sniffer.triggers.options import TriggerSpec
from sniffer.triggers.plan import Plan, Window
from sniffer.triggers.ring import FRAME, RAW, RAW_CLEAN, Ring
from sniffer.triggers.window import WindowFile, next_number, window_path

_NS = 1_000_000_000
ALIGN_NS = _NS  # how far before `t - pre` a window may start to start where nothing was pending
FIRINGS_KEPT = 100  # firings listed in a window's metadata (all are counted)


def _iso(wall_ns: int) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(wall_ns // _NS)) + f".{wall_ns % _NS // 1_000_000:03d}Z"


class TriggerSink(Sink):
    def __init__(self, spec: TriggerSpec, folder: str, stem: str, *, ids: dict | None = None, char_ns: int = 0,
                 settle_ns: int = 2 * _NS, report=None) -> None:
        self.spec = spec
        self.folder = folder
        self.stem = stem
        self.ids = ids or {}
        self.char_ns = char_ns
        self.report = report or say
        self.queries = [Query(r) for r in spec.rules]
        from sniffer.filterlang import keyword_typos

        for q in self.queries:  # said as the capture starts: an overnight trigger that can never fire
            for note in keyword_typos(q.node):
                self.report(f"note: --trigger: {note}")
        pre, post = int(spec.pre_s * _NS), int(spec.post_s * _NS)
        self.plan = Plan(len(self.queries), pre, post, settle_ns=settle_ns,
                         max_window_ns=None if spec.max_window_s is None else int(spec.max_window_s * _NS))
        self.ring = Ring(pre + ALIGN_NS, spec.ring_bytes)
        self.settled = lambda: 2  # the session binds its pipeline's (Pipeline.settled)
        self.files: dict[int, WindowFile | None] = {}  # window number -> its file (None: could not be written)
        self.written: list[str] = []
        self.window_bytes = self.window_line_bytes = 0  # the windows' files, and the line's bytes they hold
        self.failed_windows = 0
        self.last: dict | None = None
        self.runner = (CommandRunner(spec.on_trigger, spec.on_trigger_timeout_s, self.report)
                       if spec.on_trigger else None)
        self.info = None
        self.t0 = 0
        self._ctx = Context()
        self._first_n = 1
        self.decoder_state = None  # the session binds its pipeline's (Pipeline.decoder_state, state_version)
        self.state_version = None
        self._states: list[tuple[int, dict]] = []  # (ring time, decoder state from then on), oldest first
        self._version = None
        self._state_moved = False

    # ------------------------------------------------------------ the sink
    def bind(self, pipeline) -> None:
        self.decoder_state = pipeline.decoder_state
        self.state_version = pipeline.state_version

    def start(self, info) -> None:
        self.info = info
        self.t0 = info.t0_ns
        self._ctx = Context(info.t0_ns, self.ids)
        self._first_n = next_number(self.folder, self.stem)
        self._states = [(-(1 << 62), info.extra.get(KEY) or {})]

    def raw(self, event) -> None:
        data = encode_event(event)
        settled = self.settled(event.link) if event.link else self.settled()
        if type(event) is Chunk:
            bt = event.byte_t_ns
            t = bt[0] if bt else event.t_ns - len(event.data) * self.char_ns  # the first byte (as linebuf.py)
            # nothing pending (on its own link, with several): no orphan answer at a start
            kind = RAW_CLEAN if settled == 2 else RAW
        else:
            t, kind = event.t_ns, RAW
        if self._state_moved:  # what the frames before this event taught the decoders: from here on
            self._state_moved = False
            self._keep_state(t)
        self.advance(event.t_end_ns if type(event) is Gap else event.t_ns)
        self.ring.add(kind, t, event.t_ns, data)
        for w in self.plan.active:
            f = self.files.get(w.n)
            if f is None:
                continue
            if t > w.end_ns and (settled or not f.tail_open):
                # past its end, a window takes the reads that finish a frame begun (bytes wait in the framer):
                # its file has no /frames, a replay of its /raw gives its frames, the last one whole
                f.tail_open = False
                continue
            try:
                f.raw(t, event.t_ns, data, len(event.data) if type(event) is Chunk else 0)
            except Exception as e:  # noqa: BLE001 - a full disk loses the window, never the capture
                self._drop(w, f, e)

    def frame(self, frame) -> None:
        data = frame_json(frame, self.t0)
        t = frame.t_ns
        self.ring.add(FRAME, t, t, data)
        for w in self.plan.active:
            f = self.files.get(w.n)
            if f is not None and f.first_ns is not None and f.first_ns <= t <= w.end_ns:
                try:
                    f.frame(t, data)
                except Exception as e:  # noqa: BLE001
                    self._drop(w, f, e)
        if self.state_version is not None:
            v = self.state_version()
            if v != self._version:
                self._version, self._state_moved = v, True
        flags = None
        for i, q in enumerate(self.queries):
            if flags is None:
                flags = frame_flags(frame)
            if q.matches(frame, self._ctx, flags):
                self._matched(i, frame)

    def advance(self, t_ns: int) -> None:
        """Capture time is t_ns (every source event, recorded or not): complete the windows due."""
        for w in self.plan.advance(t_ns):
            self._finish(w)

    def close(self) -> None:
        try:
            for w in self.plan.finish():
                self._finish(w)
        finally:
            if self.runner is not None:
                self.runner.close()
        p = self.plan
        if not (p.fired or p.suppressed):  # a trigger that never fired says so: silence would read as "not armed"
            rules = "; ".join(f"'{_shown(r)}'" for r in self.spec.rules)
            self.report(f"triggers: 0 fired, 0 windows (no frame matched {rules})")
        else:
            self.report(f"triggers: {p.fired} fired, {len(self.written)} window files"
                        + (f", {self.failed_windows} could not be written" if self.failed_windows else "")
                        + (f", {p.suppressed} matches while their rule re-armed" if p.suppressed else ""))

    def status(self) -> dict:
        p = self.plan
        st = {"fired": p.fired, "windows": len(self.written), "open": len(p.active), "suppressed": p.suppressed,
              "window_bytes": self.window_bytes, "window_line_bytes": self.window_line_bytes,
              "failed_windows": self.failed_windows, "last": self.last, "ring_bytes": self.ring.nbytes}
        if self.runner is not None:
            st["on_trigger"] = self.runner.status()
        return {"triggers": st}

    # ------------------------------------------------------------ decoder state
    def _keep_state(self, t: int) -> None:
        state = self.decoder_state() if self.decoder_state is not None else {}
        if state != self._states[-1][1]:
            self._states.append((t, state))
        first = self.ring.first_ns
        while len(self._states) > 1 and first is not None and self._states[1][0] <= first:
            del self._states[0]  # older than anything a window can start with

    def _state_at(self, starts: dict[str, int]) -> dict:
        """The decoder state a window starts with: each link's, as it was at that link's first record."""
        out = {}
        for link, t in starts.items():
            state = next((st for ts, st in reversed(self._states) if ts <= t), self._states[0][1])
            if link is None:
                return dict(state)
            if state.get(link):
                out[link] = state[link]
        return out

    # ------------------------------------------------------------ windows
    def _matched(self, rule: int, frame) -> None:
        w, firing = self.plan.match(rule, frame.t_ns)
        if firing is not None:
            firing.detail = self._detail(rule, frame)
        if w is not None and w.n not in self.files:
            self._open(w, firing.detail)
        if firing is not None:
            self.last = dict(firing.detail, window=self._path(w))
            d = firing.detail
            joined = "" if firing is w.firings[0] else " (joins the open window)"
            self.report(f"trigger {d['rule']!r} at {d['t']:.3f} s, frame #{d['frame']}{joined}: "
                        f"{d['summary'][:160]} -> {self._path(w)}")

    def _detail(self, rule: int, frame) -> dict:
        t_rel = frame.t_ns - self.t0
        anchor = self.info.wall_anchor_ns if self.info is not None else 0
        return {"rule": self.spec.rules[rule], "t": t_rel / _NS, "time": _iso(anchor + t_rel) if anchor else None,
                "frame": frame.index, "summary": frame_line(frame, self.t0).strip(),
                "record": loads(frame_json(frame, self.t0))}

    def _path(self, w: Window) -> str:
        return window_path(self.folder, self.stem, self._first_n + w.n - 1)

    def _open(self, w: Window, first: dict) -> None:
        try:
            start = self._start(w)
            f = WindowFile(self._path(w), self.info, {k: first[k] for k in ("rule", "t", "time", "frame")},
                           self._state_at(start[-1]))
        except Exception as e:  # noqa: BLE001 - a window that cannot be written never stops the capture
            self._lost(w, e)
            return
        self.files[w.n] = f
        try:
            self._dump(w, f, start)
        except Exception as e:  # noqa: BLE001
            self._drop(w, f, e)

    def _drop(self, w: Window, f: WindowFile, e: Exception) -> None:
        self._lost(w, e, f.abandon())

    def _start(self, w: Window) -> tuple:
        """Where the window's raw events start (see the module doc): (the ring's first index to write, or per
        link with several, and {link: that record's time}; link None on one line)."""
        asked, ring = w.start_ns, self.ring
        since = asked - ALIGN_NS
        if self.info is not None and self.info.links:
            return self._start_links(asked, since)
        clean = after = None
        times: dict[int, int] = {}
        for i, (kind, t, _log, _data) in enumerate(ring.records(since)):
            if kind == FRAME:
                continue
            times.setdefault(i, t)
            if t > asked:
                after = i
                break
            if kind == RAW_CLEAN and t >= since:
                clean = i
        if clean is None:
            first = ring.first_ns
            clean = 0 if first is None or first > asked else (after if after is not None else 1 << 62)
        t0 = times.get(clean, ring.first_ns if clean == 0 and ring.first_ns is not None else asked)
        return since, clean, {None: t0}

    def _start_links(self, asked: int, since: int) -> tuple:
        """`_start` for a capture of several links: each link starts at its own last quiet point before the
        window's start (the links are seldom all quiet at once), or at its first read after it."""
        start: dict[str, tuple[int, int]] = {}  # link -> (index, time) of its first record in the window
        after: dict[str, tuple[int, int]] = {}
        for i, (kind, t, _log, data) in enumerate(self.ring.records(since)):
            if kind == FRAME:
                continue
            link = decode_event(data).link
            if t <= asked:
                if kind == RAW_CLEAN and t >= since:
                    start[link] = (i, t)
            elif link not in after:
                after[link] = (i, t)
        first = {link: start.get(link, after.get(link)) for link in start.keys() | after.keys()}
        return since, {link: i for link, (i, _) in first.items()}, {link: t for link, (_, t) in first.items()}

    def _dump(self, w: Window, f: WindowFile, start: tuple) -> None:
        """The ring's records from the window's start (`_start`) up to now into its file."""
        since, first, _times = start
        if isinstance(first, dict):  # several links: each from its own start
            for i, (kind, t, log, data) in enumerate(self.ring.records(since)):
                if kind == FRAME:
                    if f.first_ns is not None and f.first_ns <= t <= w.end_ns:
                        f.frame(t, data)
                elif t <= w.end_ns and i >= first.get(decode_event(data).link, 1 << 62):
                    f.raw(t, log, data, _line_bytes(data))
            return
        for i, (kind, t, log, data) in enumerate(self.ring.records(since)):
            if i < first:
                continue
            if kind == FRAME:
                if f.first_ns is not None and f.first_ns <= t <= w.end_ns:
                    f.frame(t, data)
            elif t <= w.end_ns:
                f.raw(t, log, data, _line_bytes(data))

    def _lost(self, w: Window, e: Exception, kept: str | None = None) -> None:
        self.files[w.n] = None
        self.failed_windows += 1
        why = getattr(e, "reason", None) or getattr(e, "strerror", None) or e
        self.report(f"error: trigger window {self._path(w)} not written: {why}"
                    + (f"; what was written is kept as {kept} (not complete)" if kept else ""))

    def _finish(self, w: Window) -> None:
        f = self.files.pop(w.n, None)
        if f is None:
            return
        meta = self._meta(w, f)
        try:
            path = f.finish(meta)
        except Exception as e:  # noqa: BLE001
            self._lost(w, e, f.output.part if f.output.state == "kept" else None)
            return
        self.written.append(path)
        try:
            self.window_bytes += os.path.getsize(path)
            self.window_line_bytes += f.line_bytes
        except OSError:
            pass  # taken away already (--on-trigger of an earlier window, a cleaner): its size is not known
        span = ((f.last_ns or 0) - (f.first_ns or 0)) / _NS
        self.report(f"window {path}: {span:.1f} s, {f.frames} frames, rules {', '.join(meta['rules'])}"
                    + ("" if meta["post_complete"] else " (the capture ended inside its post span)"))
        if self.runner is not None:
            first = w.firings[0].detail
            self.runner.submit({
                "SNIFFER_TRIGGER_FILE": os.path.abspath(path), "SNIFFER_TRIGGER_RULE": first["rule"],
                "SNIFFER_TRIGGER_RULES": "\n".join(meta["rules"]),
                "SNIFFER_TRIGGER_TIME": first["time"] or f"{first['t']:.6f}s",
                "SNIFFER_TRIGGER_T": f"{first['t']:.6f}", "SNIFFER_TRIGGER_FRAME": str(first["frame"]),
                "SNIFFER_TRIGGER_SUMMARY": first["summary"], "SNIFFER_TRIGGER_WINDOW": str(self._first_n + w.n - 1),
            })

    def _meta(self, w: Window, f: WindowFile) -> dict:
        rules = self.spec.rules
        def s(ns):
            return None if ns is None else (ns - self.t0) / _NS

        first = f.first_ns
        pre_complete = first is not None and first <= w.start_ns
        return {
            "window": self._first_n + w.n - 1, "rules": [rules[r] for r in w.rules],
            "firings": [fi.detail for fi in w.firings[:FIRINGS_KEPT]], "firings_total": len(w.firings),
            "matches": {rules[r]: n for r, n in sorted(w.matches.items())},
            "trigger_t": s(w.trigger_ns), "pre_s": self.spec.pre_s, "post_s": self.spec.post_s,
            "asked_start_t": s(w.start_ns), "start_t": s(first), "end_t": s(w.end_ns), "last_t": s(f.last_ns),
            "pre_complete": pre_complete, "post_complete": w.complete, "capped": w.capped,
            "ring_cut_t": s(self.ring.cut_ns), "raw_events": f.raw_events, "frames": f.frames,
        }


__all__ = ["ALIGN_NS", "TriggerSink"]


def _line_bytes(data: bytes) -> int:
    """The line's bytes in an encoded /raw event (the ring's)."""
    ev = decode_event(data)
    return len(ev.data) if type(ev) is Chunk else 0


def _shown(rule: str, limit: int = 80) -> str:
    """A rule as one line says it: control characters as '?', cut at `limit`."""
    text = "".join(c if c.isprintable() else "?" for c in str(rule))
    return text if len(text) <= limit else text[: limit - 3] + "..."
