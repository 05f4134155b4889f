"""The Transactions tab (issue 11): transactions built from the paired frames, the latency histogram,
and the tab under Pilot (Enter opens the request in Frames, the frame filter applies).

Expected values are computed here from the frames themselves (roles, pairs, annotations, latencies),
never from the transaction model."""

import functools
import math
import random

import pytest
from test_tui import loaded, make_app, run
from tui_helpers import SIM, replay_frames

from decoders.registry import default_registry
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.sources.files import open_replay
from sniffer.tui.app import SnifferApp
from sniffer.tui.latency import EDGES_MS, histogram_text
from sniffer.tui.store import F_PROBLEM, FrameStore
from sniffer.tui.sink import TuiSink
from sniffer.tui.transactions import BROADCAST, END_OF_CAPTURE, EXCEPTION, NO_RESPONSE, OK, ORPHAN, TIMEOUT
from sniffer.analysis.unitfigures import Latencies, UnitFigures

SIZE = (140, 45)
SCENARIOS = ["a510.mcap", "errors.mcap", "pd-series.mcap", "pd-series-ascii.mcap"]


@functools.cache
def decoded(name: str, timeout_ms: float):
    """A simulated capture decoded with a given response timeout (a bus file's [timeouts_ms])."""
    info, events = open_replay(str(SIM / name))
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1),
                 default_registry(info.devices), [], protocol=info.protocol, timeout_ms=timeout_ms)
    frames = []
    for ev in events:
        frames += p.feed(ev)
    frames += p.finish()
    return info, frames


def frames_of(name: str, timeout_ms: float | None = None):
    if timeout_ms is None:
        info, frames, _ = replay_frames(name)
        return info, frames
    return decoded(name, timeout_ms)


def store_with(frames, t0_ns=0) -> FrameStore:
    s = FrameStore(t0_ns)
    s.add(frames)
    s.transactions.sync(s.view)
    return s


def codes(f) -> set[str]:
    return {a.code for a in f.annotations}


def expected_transactions(frames) -> list[tuple]:
    """(request index or None, response index or None, kind) in order of their first frame."""
    by_index = {f.index: f for f in frames}
    out = []
    for f in frames:
        if f.role == "request":
            if f.pair is not None:
                rsp = by_index[f.pair]
                out.append((f.index, rsp.index, EXCEPTION if rsp.exception else OK))
            elif f.unit == 0:
                out.append((f.index, None, BROADCAST))
            elif "pair.timeout" in codes(f):
                out.append((f.index, None, TIMEOUT))
            elif "pair.end_of_capture" in codes(f):
                out.append((f.index, None, END_OF_CAPTURE))
            else:
                assert "pair.no_response" in codes(f), f
                out.append((f.index, None, NO_RESPONSE))
        elif f.role == "response" and (f.pair is None or f.pair not in by_index):
            out.append((None, f.index, ORPHAN))
    return out


def built(s: FrameStore) -> list[tuple]:
    txs = s.transactions
    idx = [f.index for f in s.frames]
    return [(None if txs.req[t] < 0 else idx[txs.req[t]], None if txs.rsp[t] < 0 else idx[txs.rsp[t]], txs.kind[t])
            for t in range(len(txs))]


# ------------------------------------------------------------------ the model
@pytest.mark.parametrize("name", SCENARIOS)
def test_every_request_and_response_is_in_one_transaction(name):
    info, frames = frames_of(name)
    s = store_with(frames, info.t0_ns)
    want = expected_transactions(frames)
    assert built(s) == want
    rows = [r for t in range(len(s.transactions)) for r in s.transactions.rows(t) if r >= 0]
    assert sorted(rows) == [r for r, f in enumerate(frames) if f.role in ("request", "response")]
    assert list(s.transactions.view) == list(range(len(want)))  # no filter: every one shown


def test_scenarios_give_every_kind():
    kinds = {k for name in SCENARIOS for *_, k in expected_transactions(frames_of(name)[1])}
    kinds |= {k for *_, k in expected_transactions(frames_of("errors.mcap", 20.0)[1])}
    assert {OK, EXCEPTION, NO_RESPONSE, TIMEOUT, BROADCAST, ORPHAN} <= kinds
    pd = {k for *_, k in expected_transactions(frames_of("pd-series.mcap")[1])}
    assert {OK, EXCEPTION, BROADCAST} <= pd  # 81H error reply, a broadcast write


def test_errors_with_a_short_timeout_count_timeouts_per_unit():
    """errors.mcap decoded with a 20 ms response timeout: every request left unanswered is a timeout, once
    (whether the next request or the timeout ended the wait), counted per unit apart from the latencies,
    and the exceptions are transactions of their own kind."""
    info, frames = frames_of("errors.mcap", 20.0)
    s = store_with(frames, info.t0_ns)
    assert built(s) == expected_transactions(frames)
    units = {f.unit for f in frames if f.role == "request" and f.unit}
    timeouts = 0
    for u in units:
        reqs = [f for f in frames if f.role == "request" and f.unit == u and f.pair is None]
        st = s.units[u]
        assert st.timeouts == sum(bool(codes(f) & {"pair.timeout", "pair.no_response"}) for f in reqs)
        assert st.unanswered_at_end == sum("pair.end_of_capture" in codes(f) for f in reqs)
        timeouts += st.timeouts
    assert timeouts > 0 and s.units.total().timeouts == timeouts
    both = [f for f in frames if {"pair.timeout", "pair.no_response"} <= codes(f)]
    assert both  # a request that waited past its timeout carries both codes: still one timeout
    exc = [f for f in frames if f.role == "response" and f.exception and f.pair is not None]
    assert sum(k == EXCEPTION for k in s.transactions.kind) == len(exc) > 0


def independent_figures(values: list[float]) -> dict:
    s = sorted(values)

    def rank(p):  # nearest rank: the smallest value with at least p % of the values at or below it
        return s[math.ceil(p / 100 * len(s) - 1e-9) - 1]

    return {"n": len(s), "median": rank(50), "p95": rank(95), "p99": rank(99), "max": s[-1]}


def independent_bins(values: list[float]) -> list[int]:
    bins = [0] * (len(EDGES_MS) + 1)
    for v in values:
        i = 0
        while i < len(EDGES_MS) and v > EDGES_MS[i]:
            i += 1
        bins[i] += 1
    return bins


@pytest.mark.parametrize("name", SCENARIOS)
def test_latency_per_unit_matches_the_frames(name):
    info, frames = frames_of(name)
    s = store_with(frames, info.t0_ns)
    for u in {f.unit for f in frames if f.role == "response"} | {None}:
        lat = [f.latency_ms for f in frames if f.role == "response" and f.pair is not None
               and f.latency_ms is not None and (u is None or f.unit == u)]
        st = s.units.total() if u is None else s.units[u]
        assert st.latency.bins(EDGES_MS) == independent_bins(lat)
        assert figures_of(st.latency) == (independent_figures(lat) if lat else None)
        assert st.unmeasured == sum(1 for f in frames if f.role == "response" and f.pair is not None
                                    and f.latency_ms is None and (u is None or f.unit == u))


def figures_of(lat: Latencies) -> dict | None:
    if not lat.n:
        return None
    return {"n": lat.n, "median": lat.median, "p95": lat.quantile(0.95), "p99": lat.quantile(0.99), "max": lat.max}


def test_percentiles_by_nearest_rank_and_added_after_a_look():
    fig = UnitFigures(1)
    st = fig.latency
    for v in (5.0, 1.0, 3.0, 2.0):
        st.add(v)
    assert figures_of(st) == {"n": 4, "median": 2.0, "p95": 5.0, "p99": 5.0, "max": 5.0}
    for v in range(100, 0, -1):  # added after the first figures were read
        st.add(float(v))
    values = [5.0, 1.0, 3.0, 2.0] + [float(v) for v in range(1, 101)]
    assert figures_of(st) == independent_figures(values)
    assert st.bins(EDGES_MS) == independent_bins(values)
    text = histogram_text(fig, "unit 1").plain
    assert "n 104" in text and "max 100.000 ms" in text and "timeouts 0" in text


def test_view_follows_the_store_incrementally_and_with_a_filter():
    """Batches of random size, synced after each (a live capture), give the same view as one sync at the
    end; under a filter the view is the transactions with a frame in the store's view."""
    info, frames = frames_of("errors.mcap")
    rng = random.Random(3)
    s = FrameStore(info.t0_ns)
    s.update_filter(units=frozenset({2}))
    i = 0
    while i < len(frames):
        n = rng.randint(1, 40)
        s.add(frames[i:i + n])
        s.transactions.sync(s.view)
        i += n
    txs = s.transactions
    want = sorted({txs.tx_of_row[r] for r in s.view} - {-1})
    assert list(txs.view) == want and want
    assert all(s.frame(txs.first_row(t)).unit == 2 for t in txs.view)
    full = store_with(frames, info.t0_ns)
    full.update_filter(units=frozenset({2}))
    full.transactions.sync(full.view)
    assert list(full.transactions.view) == want
    s.update_filter(units=None, roles=frozenset({"response"}))  # requests hidden: answered ones still show
    txs.sync(s.view)
    assert list(txs.view) == [t for t in range(len(txs)) if txs.rsp[t] >= 0]


def test_a_viewer_that_joins_mid_transaction_shows_the_answer_without_its_request():
    info, frames = frames_of("a510.mcap")
    first = next(i for i, f in enumerate(frames) if f.role == "request" and f.pair is not None)
    s = store_with(frames[first + 1:], info.t0_ns)  # the backlog starts after a request
    assert s.transactions.kind[0] == ORPHAN
    from sniffer.tui.txlist import format_tx

    assert f"(request #{frames[first].index} not here)" in format_tx(s, 0).plain


def test_noise_and_unknown_frames_belong_to_no_transaction():
    _, frames = frames_of("errors.mcap")
    s = store_with(frames)
    of_row = s.transactions.tx_of_row
    assert len(of_row) == len(s)
    noise = [r for r, f in enumerate(frames) if f.role not in ("request", "response")]
    assert noise and all(of_row[r] == -1 for r in noise)


# ------------------------------------------------------------------ the tab, under Pilot
def screen_text(app) -> str:
    lst = app.tx_pane.list
    return "\n".join(lst.line_text(p).plain for p in range(lst.count()))


def test_tab_4_lists_transactions_and_enter_opens_the_request():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("4")
            await pilot.pause()
            lst = app.tx_pane.list
            assert app.tabs.active == "transactions" and app.focused is lst
            frames = replay_frames()[1]
            assert lst.count() == len(expected_transactions(frames))
            assert lst.cursor == lst.count() - 1  # follows the tail, the histogram of all units meanwhile
            assert "latency, all units" in str(app.tx_pane.query_one("#histogram").render())
            text = screen_text(app)
            assert "exception 02H ILLEGAL DATA ADDRESS" in text and "no response" in text
            assert "read holding 8448..8455 (8)" in text
            await pilot.press("home", "down", "down", "down")
            tx = lst.selected_tx
            req = app.store.frame(app.store.transactions.req[tx])
            assert req.role == "request"
            await pilot.press("enter")
            assert app.tabs.active == "frames" and app.focused is app.frame_list
            assert app.selected_frame.index == req.index and app.detail.frame.index == req.index
            await pilot.press("4")
            assert lst.selected_tx == tx  # the tab keeps its place
            await pilot.click("#txlist", offset=(10, lst.cursor - round(lst.scroll_offset.y)))
            assert app.tabs.active == "frames" and app.selected_frame.index == req.index  # a click on it, too
    run(go())


def test_the_frame_filter_applies_to_transactions():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("4", "e")
            txs, lst = app.store.transactions, app.tx_pane.list
            assert 0 < lst.count() < len(txs)
            assert all(txs.flags[t] & F_PROBLEM for t in txs.view)
            head = str(app.tx_pane.query_one("#txhead").render())
            assert "filter errors" in head and "request or its response passes" in head
            await pilot.press("e", "home", "down", "down")  # u: this transaction's unit
            unit = app.store.frame(txs.first_row(lst.selected_tx)).unit
            await pilot.press("u")
            assert app.store.filter.units == {unit}
            assert lst.count() and all(app.store.frame(txs.first_row(t)).unit == unit for t in txs.view)
            await pilot.press("n")
            assert txs.flags[lst.selected_tx] & F_PROBLEM
            await pilot.press("slash", *"lat>5ms", "enter")  # the filter language: answers slower than 5 ms
            assert lst.count() and all(app.store.frame(txs.rsp[t]).latency_ms > 5 for t in txs.view)
            await pilot.press("c", "T")  # times from a reference frame (T), as the frame list shows them
            ref = app.store.time.ref_index
            assert f"from #{ref}" in str(app.tx_pane.query_one("#txhead").render())
            tx = lst.selected_tx
            assert app.store.time.text(app.store.frame(txs.first_row(tx)).t_ns) in lst.line_text(lst.cursor).plain
    run(go())


def test_histogram_figures_are_the_frames_latencies():
    async def go():
        app = make_app("a510.mcap")
        frames = replay_frames("a510.mcap")[1]
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("4", "home")
            lst = app.tx_pane.list
            unit = app.store.frame(app.store.transactions.first_row(lst.selected_tx)).unit
            for u, key in ((unit, None), (None, "h")):
                if key:
                    await pilot.press(key)
                lat = [f.latency_ms for f in frames if f.role == "response" and f.pair is not None
                       and f.latency_ms is not None and (u is None or f.unit == u)]
                fig = independent_figures(lat)
                text = str(app.tx_pane.query_one("#histogram").render())
                assert ("latency, all units" if u is None else f"latency, unit {u} (a510)") in text
                assert f"n {fig['n']}  median {fig['median']:.3f}  p95 {fig['p95']:.3f}" in text, text
                assert f"max {fig['max']:.3f} ms" in text
                counts = text.splitlines()[-1].split()
                assert counts[0] == "n" and [int(c) for c in counts[1:]] == independent_bins(lat)
    run(go())


def test_live_transactions_grow_as_frames_arrive():
    async def go():
        info, frames, registry = replay_frames("errors.mcap")
        sink = TuiSink()
        sink.start(info)
        sink.frames(frames[:100])
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.press("4")
            lst = app.tx_pane.list
            first = lst.count()
            assert first == len(expected_transactions(frames[:100]))
            await pilot.press("space")  # paused: the list holds still while frames come in
            sink.frames(frames[100:])
            app.poll()
            await pilot.pause()
            assert lst.count() == first and "(paused)" in str(app.tx_pane.query_one("#txhead").render())
            await pilot.press("space")
            await pilot.pause()
            assert lst.count() == len(expected_transactions(frames)) > first
            assert lst.cursor == lst.count() - 1
    run(go())


@pytest.mark.parametrize("name", ["pd-series.mcap", "pd-series-ascii.mcap"])
def test_pd_series_point_selection_lights_its_bytes(name):
    """Selecting a PD-series point in the detail tree highlights its value's bytes in the hex dump (the
    characters of the value in PD ASCII)."""
    from sniffer.tui.detail import HL

    async def go():
        app = make_app(name)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home")
            seen = set()
            for _ in range(40):
                f = app.selected_frame
                if f.points and f.function not in seen:
                    seen.add(f.function)
                    await pilot.press("enter")
                    tree = app.detail.query_one("Tree")
                    p = f.points[0]
                    label = f"{'-' if p['address'] is None else p['address']}{' ' + p['id'] if p.get('id') else ''} "
                    label += f"{p['name']} = "  # the point's node (detail.py), not the summary's
                    assert app.focused is tree and str(tree.cursor_node.label).startswith(label)  # Enter: the point
                    s, e = app.detail.span
                    assert [s, e] == p["span"]
                    value = f.raw[s:e]
                    if name.endswith("ascii.mcap"):
                        value = bytes.fromhex(value.decode())
                    assert int.from_bytes(value, "big") == p["raw"]
                    hexdump = app.detail.query_one("#hex").content
                    lit = "".join(hexdump.plain[sp.start:sp.end] for sp in hexdump.spans if str(sp.style) == HL)
                    assert lit.replace(" ", "").startswith(f.raw[s:e].hex()), (lit, f.raw[s:e].hex())
                    await pilot.press("escape")
                await pilot.press("down")
            assert len(seen) >= 3  # status, parameter and control answers at least
    run(go())
