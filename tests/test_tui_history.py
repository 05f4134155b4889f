"""Register history (sniffer/analysis/history.py) and the plot's model (plotmodel.py), without Textual:
on simulated captures, checked against what the frames themselves carried."""

import functools
import random

import pytest
from tui_helpers import replay_frames

from sniffer.analysis.history import BUDGET, CAP, CHANGE, GAP, Series, cap_for
from sniffer.tui.store import FrameStore
from sniffer.tui.plotaxis import nice_step, tick_text
from sniffer.tui.plotmodel import PlotSet, TimeWindow, Trace, column_ranges, render
from sniffer.tui.timebase import TimeBase

FREQ_OUT, FREQ_CMD, CURRENT = 0x2524, 0x2502, 0x2527  # A510: output frequency, frequency command, current
FREQ_CMD_SEEN = 0x2523  # the frequency command as the monitor block reports it (read every cycle)


def carried(frames, unit: int, address: int, table: str = "holding") -> list[tuple[int, int, int]]:
    """(t_ns, frame index, raw) of every frame that brought the register a value (its `writes`)."""
    out = []
    for f in frames:
        if f.unit != unit or f.protocol == "noise":
            continue
        for wtable, start, raws in f.writes:
            if wtable == table and start <= address < start + len(raws):
                out.append((f.t_ns, f.index, raws[address - start]))
    return out


def changes_of(samples: list[tuple[int, int, int]]) -> list[tuple[int, int, int | None, int]]:
    """(t_ns, index, old raw, new raw) of the first sample and every one whose raw differs from the one before."""
    out, prev = [], None
    for t, ix, raw in samples:
        if prev is None or raw != prev:
            out.append((t, ix, prev, raw))
        prev = raw
    return out


@functools.cache
def long_a510(seconds: float = 120.0):
    """A 120 s a510 capture (the drives ramp their output frequency up and down), decoded."""
    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.simulator.scenario import get_scenario
    from sniffer.simulator.sources import SimulatedSource

    sc = get_scenario("a510")
    session = Session(CaptureSpec(), SimulatedSource(sc, sc.line, seconds, seed=3))
    session.open()
    return list(session)


def test_history_holds_every_sample_with_its_time_and_frame():
    info, frames, _ = replay_frames("a510.mcap")
    s = FrameStore(info.t0_ns)
    s.add(frames)
    for unit in (1, 2):
        rv = s.registers[(unit, "holding", FREQ_OUT)]
        truth = carried(frames, unit, FREQ_OUT)
        h = rv.history
        assert len(truth) > 50 and h.seen == len(h) == len(truth)
        assert list(zip(h.t, h.ix)) == [(t, ix) for t, ix, _ in truth]
        assert [round(v * 100) for v in h.v] == [raw for _, _, raw in truth]  # 0.01 Hz
        assert max(h.v) > 20 and min(h.v) == 0  # it ramps
        assert h.changes == len(changes_of(truth)) - 1 == rv.changes


def test_change_log_is_the_changes_at_their_frames():
    info, frames, _ = replay_frames("a510.mcap")
    s = FrameStore(info.t0_ns)
    s.add(frames)
    for address in (FREQ_OUT, FREQ_CMD):
        h = s.registers[(1, "holding", address)].history
        truth = changes_of(carried(frames, 1, address))
        log = [h.change(p) for p in h.change_positions()]
        assert [(t, ix) for t, ix, *_ in log] == [(t, ix) for t, ix, _, _ in truth]
        assert [None if old is None else round(old * 100) for _, _, old, _, _ in log] == [o for *_, o, _ in truth]
        assert [round(new * 100) for _, _, _, new, _ in log] == [n for *_, n in truth]
        assert not any(gap for *_, gap in log)
    assert len(log) < h.seen  # a log of changes, not of samples


def _bucket_of(h: Series, t: int) -> int:
    return (t - h.origin) // h.width


@pytest.mark.parametrize("cap", [64, 256])
def test_thinned_history_is_bounded_and_true_to_the_capture(cap):
    """Past the cap the history keeps, per time bucket, the first sample, the extremes and the start of the
    final value: each kept sample is a real one, each bucket's min and max survive, and a change listed
    without the 'thinned' mark is a real change from the value listed before it."""
    frames = long_a510()
    s = FrameStore(frames[0].t_ns, history_cap=cap)
    for i in range(0, len(frames), 500):  # in batches, as the UI takes them
        s.add(frames[i:i + 500])
        assert all(len(rv.history) <= cap for rv in s.registers.values())
    assert sum(1 for rv in s.registers.values() if rv.history.thins) > 30
    for (unit, table, address), rv in s.registers.items():
        h = rv.history
        truth = carried(frames, unit, address, table)
        value_of = {ix: raw for _, ix, raw in truth}
        scale = next((v / value_of[ix] for v, ix in zip(h.v, h.ix) if value_of[ix]), 1.0)
        t_of = {ix: t for t, ix, _ in truth}
        assert h.seen == len(truth) and h.changes == len(changes_of(truth)) - 1
        for t, v, ix in zip(h.t, h.v, h.ix):
            assert t_of[ix] == t and v == pytest.approx(value_of[ix] * scale)
        assert h.v[-1] == pytest.approx(truth[-1][2] * scale)
        if not h.thins:
            assert len(h) == len(truth)
            continue
        buckets: dict[int, list] = {}
        for t, _, raw in truth:
            buckets.setdefault(_bucket_of(h, t), []).append(raw)
        kept: dict[int, list] = {}
        for t, v in zip(h.t, h.v):
            kept.setdefault(_bucket_of(h, t), []).append(v)
        assert kept.keys() == buckets.keys()
        for b, raws in buckets.items():
            assert min(kept[b]) == pytest.approx(min(raws) * scale) and max(kept[b]) == pytest.approx(max(raws) * scale)
        previous = {ix: (truth[i - 1][2] if i else None) for i, (_, ix, _) in enumerate(truth)}
        for p in h.change_positions():
            t, ix, old, new, gap = h.change(p)
            if not gap and p:
                assert previous[ix] is not None and old == pytest.approx(previous[ix] * scale) != new


def test_a_rarely_changing_register_keeps_every_change_when_thinned():
    frames = long_a510()
    s = FrameStore(frames[0].t_ns, history_cap=256)
    s.add(frames)
    h = s.registers[(1, "holding", FREQ_CMD_SEEN)].history
    truth = changes_of(carried(frames, 1, FREQ_CMD_SEEN))
    per_bucket: dict[int, int] = {}
    for t, *_ in truth:
        per_bucket[_bucket_of(h, t)] = per_bucket.get(_bucket_of(h, t), 0) + 1
    assert h.thins and len(h) < h.seen / 4 and max(per_bucket.values()) <= 3  # thinned, changes sparse
    log = [h.change(p) for p in h.change_positions()]
    assert [ix for _, ix, *_ in log] == [ix for _, ix, _, _ in truth]
    assert not any(gap for *_, gap in log)


def test_series_thinning_on_synthetic_signals():
    """A constant, a step and a noisy signal of 100,000 samples each, cap 512."""
    rng = random.Random(5)
    x, step = 10, []
    for _ in range(100_000):
        if rng.random() < 0.0005:
            x = rng.choice([10, 20, 30, 40])
        step.append(x)
    signals = {"constant": [5.0] * 100_000, "step": step, "noisy": [rng.gauss(50, 5) for _ in range(100_000)]}
    for name, values in signals.items():
        h = Series(512)
        for i, v in enumerate(values):
            h.add(i * 10_000_000, v, i)
        assert len(h) <= 512 and h.seen == len(values), name
        assert (min(h.v), max(h.v), h.v[-1]) == (min(values), max(values), values[-1]), name
        assert h.fl[0] & CHANGE and all(values[ix] == v for v, ix in zip(h.v, h.ix)), name
        if name == "constant":
            assert h.change_positions() == [0] and h.changes == 0
        if name == "noisy":
            assert any(f & GAP for f in h.fl)  # changes thinned out, and marked so
    assert h.nearest(50_000.5 * 10_000_000)[2] in range(49_000, 51_000)
    assert h.nearest(10**18) == (99_999 * 10_000_000, h.v[-1], 99_999) == (*h.end[:1], h.v[-1], h.end[1])


def test_a_block_reaching_its_cap_together_is_thinned_a_few_histories_per_frame():
    """A poll of 125 registers brings every history to its cap with the same frame: thinning them all at
    once held the UI for 90 ms.  They queue, the book thins THIN_PER_FRAME of them per frame, none grows
    past twice its cap, and once the queue is empty each is back within its cap and true to its samples."""
    from sniffer.frame import Frame
    from sniffer.analysis.register_book import THIN_PER_FRAME, RegisterBook

    cap, n, polls = 64, 40, 400
    book = RegisterBook(cap)
    rng = random.Random(4)
    truth: dict[int, list] = {}
    for k in range(polls):
        values = [rng.randint(0, 3) for _ in range(n)]
        f = Frame(k, k * 10_000_000, k * 10_000_000 + 1, b"", "modbus-rtu", 1, 3)
        f.crc_ok, f.role, f.writes = True, "response", [["holding", 0, values]]
        before = sum(rv.history.thins for rv in book.values.values())
        book.frame(f)
        assert sum(rv.history.thins for rv in book.values.values()) - before <= THIN_PER_FRAME
        assert all(len(rv.history) <= 2 * cap for rv in book.values.values())
        for a, v in enumerate(values):
            truth.setdefault(a, []).append((k, v))
    assert not book.thin_queue and all(rv.history.thins for rv in book.values.values())
    for a in range(n):
        h = book.values[(1, "holding", a)].history
        kept = dict(truth[a])
        assert len(h) <= cap and h.seen == polls and all(kept[ix] == v for v, ix in zip(h.v, h.ix))
        assert (min(h.v), max(h.v)) == (min(kept.values()), max(kept.values()))


def test_many_registers_share_the_history_budget():
    assert [cap_for(n) for n in (1, 128, 644, 5000)] == [CAP, CAP, BUDGET // 644, 1024]
    info, frames, _ = replay_frames("errors.mcap")
    s = FrameStore(info.t0_ns)
    s.add(frames)
    n = len(s.registers)
    assert n > 128 and {rv.history.cap for rv in s.registers.values()} == {BUDGET // n}
    assert n * BUDGET // n * 25 <= 27_000_000  # 25 bytes a sample: the budget is about 26 MB


# ---------------------------------------------------------------- plot model
def _brute_columns(h: Series, lo: float, hi: float, n: int):
    """Per column: min and max of the step line's values over [c_lo, c_hi), None where it has none."""
    out = []
    dt = (hi - lo) / n
    for c in range(n):
        a, b = lo + c * dt, lo + (c + 1) * dt
        before = [v for t, v in zip(h.t, h.v) if t < a]
        inside = [v for t, v in zip(h.t, h.v) if a <= t < b]
        vals = inside + before[-1:]
        if not inside and (not before or a > h.end[0]):
            out.append(None)
        else:
            out.append((min(vals), max(vals)))
    return out


def test_plot_columns_are_the_min_and_max_of_the_step_line():
    info, frames, _ = replay_frames("a510.mcap")
    s = FrameStore(info.t0_ns)
    s.add(frames)
    h = s.registers[(2, "holding", CURRENT)].history
    for lo, hi, n in ((info.t0_ns, s.last_t_ns, 200), (h.t[10] - 1e8, h.t[30] + 3e8, 37), (h.t[5], h.t[6], 8)):
        assert column_ranges(h, lo, hi, n) == _brute_columns(h, lo, hi, n)


def test_time_window_zoom_pan_and_follow():
    w = TimeWindow()
    lo_all, hi_all = 0.0, 100e9
    assert w.range(lo_all, hi_all) == (0, 100e9) and w.following
    w.zoom(0.5, None, lo_all, hi_all)  # following: around the end, still following
    assert w.range(lo_all, hi_all) == (50e9, 100e9) and w.following
    assert w.range(lo_all, 120e9) == (70e9, 120e9)  # more frames: the window moves with the tail
    w.zoom(0.5, 80e9, lo_all, 120e9)  # around a cursor: it stays where it is on screen
    lo, hi = w.range(lo_all, 120e9)
    assert (hi - lo, (80e9 - lo) / (hi - lo)) == (25e9, pytest.approx(0.2)) and not w.following
    assert w.range(lo_all, 200e9) == (lo, hi)  # not at the end: the window stays
    w.pan(-1, lo_all, 200e9)
    assert w.range(lo_all, 200e9) == (lo - 25e9, lo)
    w.pan(100, lo_all, 200e9)  # panned to the end: following again
    assert w.following and w.range(lo_all, 200e9) == (175e9, 200e9)
    w.zoom(64, None, lo_all, 200e9)
    assert w.span is None and w.range(lo_all, 200e9) == (0, 200e9)
    w.zoom(1e-9, 10e9, lo_all, 200e9)
    assert w.span == 1_000_000  # a millisecond at most


def test_ticks_and_labels():
    assert [nice_step(10, 5), nice_step(0.7, 7), nice_step(2500, 4)] == [2, 0.1, 1000]
    assert [tick_text(1.5, 0.5), tick_text(-0.0, 0.1), tick_text(120, 20), tick_text(123456789, 1)] == \
        ["1.5", "0.0", "120", "1.2e+08"]


def test_render_two_units_and_hit_tests():
    info, frames, _ = replay_frames("a510.mcap")
    s = FrameStore(info.t0_ns)
    s.add(frames)
    plots = PlotSet()
    for k in ((1, "holding", FREQ_OUT), (1, "holding", CURRENT), (1, "holding", 0x2521)):
        assert plots.add(k)
    assert not plots.add((1, "holding", FREQ_OUT))
    traces = [Trace(k, s.registers[k].name, s.registers[k].eng_unit or "", plots.colours[k], s.registers[k].history)
              for k in plots.keys]
    img = render(traces, info.t0_ns, s.last_t_ns, 120, 30, TimeBase(t0_ns=info.t0_ns))
    assert [(a.unit, a.side) for a in img.axes] == [("Hz", "left"), ("A", "right"), ("", "scaled")]
    assert len(img.lines) == 30 and all(sum(len(t) for t, _ in line) == 120 for line in img.lines)
    assert "Hz" in img.lines[0][0][0] and "A" in img.lines[0][-1][0]
    assert img.axes[0].lo <= 0 and img.axes[0].hi >= max(traces[0].series.v)
    labels = "".join(t for t, _ in img.lines[-1])
    assert labels.split()[:3] == ["0", "2", "4"] and labels.endswith(" s")
    for x in (img.x0, img.x0 + img.cols // 2, img.x0 + img.cols - 1):
        assert img.column_of(img.time_at(x)) == x - img.x0
    c = img.cols // 3
    top, bottom = img.spans[1][c]
    assert img.trace_at(img.x0 + c, img.top + top) in {i for i, sp in enumerate(img.spans) if sp[c] and
                                                       sp[c][0] <= top <= sp[c][1]}
    assert img.trace_at(img.x0 - 1, img.top) is None
