"""The TUI's store and sink, without Textual."""

import random
import threading

import pytest
from tui_helpers import SIM_CAPTURES, registry_shadow, replay_frames, store_of

from sniffer.filterlang import Context, Query
from sniffer.tui.filters import filter_expr, parse_filter
from sniffer.tui.framepack import pack, unpack
from sniffer.tui.store import F_EXC, F_NOISE, F_PROBLEM, F_TIMEOUT, Filter, FrameStore, frame_flags
from sniffer.tui.sink import TuiSink


def test_every_frame_in_view_and_rows_map_indexes():
    _, frames, _ = replay_frames()
    s = store_of()
    assert len(s) == len(frames) == len(s.view)
    for row, f in enumerate(s.frames):
        assert s.row_of[f.index] == row


def test_pairs_point_at_each_other():
    s = store_of()
    pairs = 0
    for row, f in enumerate(s.frames):
        pr = s.pair_row(row)
        if pr is not None:
            pairs += 1
            assert s.frames[pr].pair == f.index
            assert {f.role, s.frames[pr].role} == {"request", "response"}
    assert pairs > 100


def test_filter_by_unit_function_role_text():
    s = store_of()
    s.update_filter(units=frozenset({2}))
    assert s.view and all(s.frame_at(i).unit == 2 for i in range(len(s.view)))
    s.update_filter(units=None, functions=frozenset({3}))
    assert s.view and all(s.frame_at(i).function & 0x7F == 3 for i in range(len(s.view)))
    s.update_filter(functions=None, roles=frozenset({"noise"}))
    assert s.view and all(s.frame_at(i).protocol == "noise" for i in range(len(s.view)))
    s.update_filter(roles=None, text="ILLEGAL DATA")
    assert s.view and all(s.frame_at(i).exception for i in range(len(s.view)))
    s.update_filter(text="")
    assert len(s.view) == len(s)


def test_errors_only_and_next_previous_problem():
    s = store_of()
    s.update_filter(errors_only=True)
    assert 0 < len(s.view) < len(s)
    assert all(s.flags[r] & F_PROBLEM for r in s.view)
    kinds = 0
    for r in s.view:
        kinds |= s.flags[r]
    assert kinds & F_EXC and kinds & F_NOISE and kinds & F_TIMEOUT
    s.update_filter(errors_only=False)
    first = s.next_problem(-1)
    assert first == s.problems[0]
    second = s.next_problem(first)
    assert second == s.problems[1]
    assert s.next_problem(second, forward=False) == first
    assert s.next_problem(first, forward=False) is None
    assert s.next_problem(len(s)) is None


def test_next_problem_respects_filter():
    s = store_of()
    s.update_filter(units=frozenset({9}))
    r = s.next_problem(-1)
    assert r is not None and s.frames[r].unit == 9


def test_unit_stats_count_and_latency():
    s = store_of()
    st = s.units[1]
    frames = [f for f in s.frames if f.unit == 1]
    assert st.requests == sum(f.role == "request" for f in frames)
    assert st.responses == sum(f.role == "response" for f in frames)
    assert st.crc_errors == sum(f.crc_ok is False for f in frames)
    assert st.exceptions == sum(bool(f.exception) for f in frames) > 0
    assert st.lat_min <= st.lat_median <= st.lat_max
    assert st.poll_rate > 0
    assert s.units[9].timeouts > 0 and s.units[9].responses == 0


def test_pause_freezes_view_and_resume_catches_up():
    info, frames, _ = replay_frames()
    s = FrameStore(info.t0_ns)
    s.add(frames[:100])
    s.pause(True)
    s.add(frames[100:])
    assert len(s.view) == 100 and len(s) == len(frames)
    assert sum(u.requests for u in s.units.values()) > 50  # stats go on while paused
    s.update_filter(units=frozenset({1}))
    assert all(r < 100 for r in s.view)
    s.pause(False)
    assert any(r >= 100 for r in s.view)


def test_bookmarks():
    s = store_of()
    assert s.toggle_bookmark(10) and s.toggle_bookmark(40)
    assert s.next_bookmark(-1) == 10 and s.next_bookmark(10) == 40 and s.next_bookmark(40) is None
    assert s.next_bookmark(40, forward=False) == 10
    assert not s.toggle_bookmark(10)
    assert s.next_bookmark(-1) == 40


def test_register_shadow_tracks_values_and_changes():
    s = store_of("a510.mcap")
    rows = s.register_rows(1)
    assert rows and all(r.unit == 1 for r in rows)
    named = [r for r in rows if r.name and not r.name.startswith("holding[")]
    assert named, "model register names reach the watch"
    assert any(r.changes for r in rows)
    assert any(len(r.history) > 1 for r in rows)


def test_parse_filter_and_back():
    kw = parse_filter("u:1,2 fc:0x10,3 role:req,rsp err crc bad")
    assert kw["units"] == {1, 2} and kw["functions"] == {16, 3}
    assert kw["roles"] == {"request", "response"} and kw["errors_only"] and kw["text"] == "crc bad"
    assert parse_filter(filter_expr(Filter(**kw))) == kw


def test_sink_is_thread_safe_and_batches():
    _, frames, _ = replay_frames()
    sink = TuiSink()
    n_threads, per = 4, len(frames)

    def push():
        for f in frames:
            sink.frame(f)

    threads = [threading.Thread(target=push) for _ in range(n_threads)]
    for t in threads:
        t.start()
    got = []
    while any(t.is_alive() for t in threads) or sink.backlog:
        got += sink.drain(limit=500)
    for t in threads:
        t.join()
    got += sink.drain()
    assert len(got) == n_threads * per


def test_model_and_sink_do_not_import_textual():
    import subprocess
    import sys

    code = ("import sys, sniffer.tui.store, sniffer.tui.sink, sniffer.tui.filters, sniffer.tui.goto; "
            "sys.exit(1 if any(m == 'textual' or m.startswith('textual.') for m in sys.modules) else 0)")
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_records_round_trip_into_the_store():
    from sniffer.formats.records import frame_record

    info, frames, _ = replay_frames()
    a, b = FrameStore(info.t0_ns), FrameStore(info.t0_ns)
    a.add(frames)
    b.add_records(frame_record(f, info.t0_ns) for f in frames)
    assert list(a.flags) == list(b.flags) and list(a.problems) == list(b.problems)
    assert [(f.index, f.pair, f.role, f.summary) for f in a.frames] == [(f.index, f.pair, f.role, f.summary)
                                                                        for f in b.frames]
    ua, ub = a.units[1], b.units[1]
    assert (ua.requests, ua.responses, ua.exceptions, ua.timeouts) == (ub.requests, ub.responses, ub.exceptions,
                                                                        ub.timeouts)


# ---------------------------------------------------------------- the compact store
def _brute_passes(f, flags, flt, ctx) -> bool:
    """The filter frame by frame: its fields as the store applied them when it kept every Frame (written out
    again, independently), its text in the filter language's meaning on one frame (test_filterlang.py holds
    that against the decoded frames)."""
    if flt.errors_only and not flags & F_PROBLEM:
        return False
    if flt.units is not None and f.unit not in flt.units:
        return False
    if flt.functions is not None and (f.function is None or (f.function & 0x7F) not in flt.functions):
        return False
    if flt.roles is not None and f.role not in flt.roles:
        return False
    return not flt.text or Query(flt.text).matches(f, ctx)


def _all_frames():
    info, a, _ = replay_frames("errors.mcap")
    _, b, _ = replay_frames("a510.mcap")
    return info, list(a) + list(b)


def test_compact_store_gives_back_what_was_added_across_blocks_and_eviction():
    from sniffer.formats.records import frame_record
    from sniffer.tui.framepack import pack

    info, frames = _all_frames()
    s = FrameStore(info.t0_ns, block=16, frame_cache=8)
    s.add(frames[:100])
    s.add(frames[100:])
    assert len(s) == len(frames) and s.blocks.sealed_rows == len(frames) // 16 * 16 and s.blocks.tail
    s.blocks.clear_cache()
    order = list(range(len(frames)))
    random.Random(3).shuffle(order)  # jump between blocks: the caches evict all the time
    for row in order + order[:50]:
        got, want = s.frame(row), frames[row]
        assert frame_record(got, info.t0_ns) == frame_record(want, info.t0_ns)
        assert pack(got) == pack(want)  # every slot, not only what the record says
        assert got.annotations == want.annotations and all(type(a) is type(w) for a, w in
                                                           zip(got.annotations, want.annotations))
    assert s.frames[-1].index == frames[-1].index and [f.index for f in s.frames[3:6]] == [3, 4, 5]
    assert [f.index for f in s.frames] == [f.index for f in frames]
    assert len(s.frames) == len(frames)
    for row in range(len(frames)):
        assert s.pair_row(row) == (None if frames[row].pair is None else s.row_of.get(frames[row].pair))
        assert s.t_ns[row] == frames[row].t_ns


class Level:  # a decoder's own type in a point: marshal cannot write it, pickle can
    def __init__(self, v):
        self.v = v

    def __eq__(self, other):
        return isinstance(other, type(self)) and other.v == self.v


@pytest.mark.parametrize("local", [False, True], ids=["pickled", "kept as objects"])
def test_compact_store_keeps_a_value_marshal_cannot_write(local):
    from sniffer.frame import Frame

    class LocalLevel(Level):  # not even picklable
        pass

    kind = LocalLevel if local else Level
    s = FrameStore(block=4, frame_cache=1)
    for i in range(9):
        f = Frame(i, i * 1000, i * 1000 + 500, bytes([1, 3, 0, i]), "modbus-rtu", 1, 3)
        f.points = [{"name": "x", "address": i, "raw": i, "value": kind(i), "unit": None}]
        s.add([f])
    s.blocks.clear_cache()
    assert [s.frame(r).points[0]["value"] for r in range(9)] == [kind(i) for i in range(9)]
    s.update_filter(text="0103")
    assert list(s.view) == list(range(9))


FILTERS = [
    {"units": frozenset({2})}, {"units": frozenset({1, 9})}, {"functions": frozenset({3})},
    {"functions": frozenset({16}), "errors_only": True}, {"roles": frozenset({"noise"})},
    {"roles": frozenset({"request", "unknown"})}, {"errors_only": True},
    {"text": "illegal"}, {"text": "ILLEGAL DATA"}, {"text": "crc"}, {"text": "0110"}, {"text": "10200"},
    {"text": "modbus.crc.mismatch"}, {"text": "a510"}, {"text": "noise"}, {"text": "request"},
    {"text": "response", "units": frozenset({2})}, {"text": "frequency", "roles": frozenset({"response"})},
    {"text": "no such thing"}, {"units": frozenset({3}), "text": "timeout", "errors_only": True},
    # the filter language: what the columns answer, what the search text answers, what only the frames can
    {"text": "reg:8448..8450"}, {"text": "reg:2520H"}, {"text": "reg:holding[8192] or reg:coil[3]"},
    {"text": "2524H"}, {"text": "holding[8455]"}, {"text": "lat>5ms"}, {"text": "lat:..3ms"},
    {"text": "t:2s..4s"}, {"text": "t>20s or t<1s"}, {"text": "lat>2.5005ms or t<=1.0000000005s"},
    {"text": "lat<3ms lat>=2000.5us u:0..3"}, {"text": "!u:1 (fc:3 or exc)"}, {"text": "model:a510 fault"},
    {"text": "not (crc or noise) role:rsp"}, {"text": '"Output frequency" > 10'}, {"text": "holding[8449] >= 3000"},
    {"text": '"Error description (fault code)" = OV'}, {"text": '"output current" u:2'}, {"text": "u!=1 fc=16"},
    {"text": "2524H >= 0.5Hz or warn"}, {"text": '"State signal (status word)" ~ "operation=run"'},
    {"units": frozenset({1}), "text": '"Output frequency" != 0'}, {"text": "Hz !u:2"},
]


def _filter_id(kw: dict) -> str:
    """A test id that is the same in every process: a set's members sorted (a frozenset of strings prints in its
    hash order, which changes with the process, and pytest-xdist's workers must collect the same ids)."""
    return " ".join(f"{k}={{{','.join(map(str, sorted(v)))}}}" if isinstance(v, frozenset) else f"{k}={v}"
                    for k, v in kw.items())


@pytest.mark.parametrize("kw", FILTERS, ids=_filter_id)
def test_filters_give_the_rows_a_brute_force_check_gives(kw):
    info, frames = _all_frames()
    s = FrameStore(info.t0_ns, block=32)
    s.add(frames[:300])
    flt = s.update_filter(**kw)
    s.add(frames[300:])  # arriving under the filter: the per-frame test
    flags = [frame_flags(f) for f in frames]
    ctx = Context(info.t0_ns)
    want = [r for r, f in enumerate(frames) if _brute_passes(f, flags[r], flt, ctx)]
    assert list(s.view) == want
    s.set_filter(flt)  # rebuilt from the columns and the packed search text
    assert list(s.view) == want
    s.pause(True)
    s.add(frames[:40])  # paused: the view keeps its range
    s.update_filter(**kw)
    assert list(s.view) == want


def test_row_index_takes_frames_out_of_order():
    from sniffer.tui.store import RowIndex

    ix = RowIndex()
    for row, index in enumerate([0, 1, 5, 3, 6, 7, 2, 9]):
        ix.add(index, row)
    assert [ix.get(i) for i in (0, 1, 5, 3, 6, 7, 2, 9)] == list(range(8))
    assert ix.get(4) is None and 8 not in ix and ix[9] == 7


# ---------------------------------------------------------------- register watch from the frames' writes
def _watch(store) -> dict:
    return {k: (rv.name, rv.id, rv.value, rv.eng_unit, rv.text, rv.raw, rv.changes, rv.t_ns, rv.changed_ns,
                list(rv.history)) for k, rv in store.registers.items()}


@pytest.mark.parametrize("name", SIM_CAPTURES)
def test_register_watch_is_the_decoders_shadow_locally_and_from_records(name):
    """Local frames and the same frames' JSON records (what an attached viewer gets) build one watch,
    and it is the registry's final shadow."""
    from sniffer.formats.records import frame_json, loads

    info, frames, registry = replay_frames(name)
    local = FrameStore(info.t0_ns)
    local.add(frames[:57])
    local.add(frames[57:])
    attached = FrameStore(info.t0_ns)
    attached.add_records(loads(frame_json(f, info.t0_ns)) for f in frames)
    shadow = registry_shadow(registry)
    assert shadow and {k: rv.raw for k, rv in local.registers.items()} == shadow
    assert _watch(attached) == _watch(local)
    rows = local.register_rows()
    assert any(rv.changes for rv in rows) and any(len(rv.history) > 1 for rv in rows)
    for rv in rows:  # a value decoded from the shadow's raw, never a stale one
        if rv.history:
            assert rv.history[-1] == float(rv.value)


@pytest.mark.parametrize("name", SIM_CAPTURES)
def test_books_that_took_the_frames_later_are_the_books_that_took_them_as_they_came(name):
    """A replay loading fills the list first (add(books=False)); the register book and the diagnosis take
    the frames afterwards from the packed blocks (catch_up, in turns). They end as the books of a store
    that took every frame as it came: every register's value, changes and history, every finding; and
    frames added while they are behind wait their turn (order kept)."""
    info, frames, registry = replay_frames(name)
    now = FrameStore(info.t0_ns, block=16)
    now.start_diagnosis(info, registry)
    now.add(frames)
    later = FrameStore(info.t0_ns, block=16)
    later.start_diagnosis(info, registry)
    half = len(frames) // 2
    later.add(frames[:half], books=False)
    assert later.books_behind == half and not later.registers
    later.add(frames[half:half + 5])  # books behind: these wait too, not applied out of order
    assert later.books_behind == half + 5 and not later.registers
    later.add(frames[half + 5:], books=False)
    turns = 0
    while later.books_behind:
        later.catch_up(budget_s=0.0)  # at least 64 frames a turn
        turns += 1
    assert turns > 1 and later.booked == len(later) == len(frames)
    assert _watch(later) == _watch(now)
    assert [x.to_dict() for x in later.diagnosis.findings()] == [x.to_dict() for x in now.diagnosis.findings()]
    later.add(frames[:3])  # caught up: frames go to the books as they come again
    assert later.books_behind == 0


def _modbus(index, t_ms, role, pair=None, points=(), writes=(), unit=1, function=0x10, crc_ok=True):
    from sniffer.frame import Frame

    f = Frame(index, t_ms * 1_000_000, t_ms * 1_000_000 + 500_000, b"\x00", "modbus-rtu", unit, function,
              crc_ok=crc_ok)
    f.role, f.pair, f.points, f.writes = role, pair, [dict(p) for p in points], [list(w) for w in writes]
    return f


def test_the_watch_applies_writes_named_by_a_point_with_that_raw():
    pt = {"name": "Frequency command", "address": 8192, "raw": 7, "value": 0.07, "unit": "Hz", "id": "F"}
    s = FrameStore()
    s.add([_modbus(0, 0, "request", points=[pt])])
    assert not s.registers  # a request writes nothing: its points only name what a write may bring
    s.add([_modbus(1, 5, "response", pair=0, writes=[["holding", 8192, [7]]])])
    rv = s.registers[(1, "holding", 8192)]
    assert (rv.name, rv.value, rv.eng_unit, rv.raw, rv.changes) == ("Frequency command", 0.07, "Hz", 7, 0)
    s.add([_modbus(2, 10, "response", function=0x16, writes=[["holding", 8192, [9]]])])  # no point says 9
    # the raw number is the register's, not a frequency: a series of its own (never 9 Hz after 0.07 Hz)
    assert (rv.name, rv.value, rv.eng_unit, rv.raw, rv.changes, rv.changed_ns) == \
           ("holding[8192]", 9, None, 9, 1, 10_000_000)
    s.add([_modbus(3, 15, "request", points=[dict(pt, raw=9, value=0.09)], crc_ok=False),  # a mangled frame
           _modbus(4, 20, "response", function=0x16, writes=[["holding", 8192, [9]]])])  # names nothing
    assert (rv.value, rv.raw, rv.changes, list(rv.history)) == (9, 9, 1, [9, 9])
    s.add([_modbus(5, 25, "response", function=0x03, points=[dict(pt, raw=9, value=0.09)],
                   writes=[["holding", 8192, [9]], ["coil", 3, [1, 0]]])])
    assert (rv.name, rv.value, rv.eng_unit, rv.raw, rv.changes, list(rv.history)) == \
           ("Frequency command", 0.09, "Hz", 9, 1, [0.09])
    assert {k: v.raw for k, v in s.registers.items() if k[1] == "coil"} == {(1, "coil", 3): 1, (1, "coil", 4): 0}


def test_store_maps_rows_when_frames_arrive_out_of_order():
    info, frames = _all_frames()
    order = frames[:10] + [frames[12], frames[10], frames[11]] + frames[13:60]
    s = FrameStore(info.t0_ns, block=8)
    s.add(order)
    for row, f in enumerate(order):
        assert s.row_of[f.index] == row and s.frame(row).index == f.index


def _frames_every(n, step_ns):
    from sniffer.frame import Frame

    return [Frame(i, i * step_ns, i * step_ns + 1000, b"\x01\x03", "modbus-rtu", 1, 3) for i in range(n)]


def test_sink_makes_a_replay_wait_for_the_ui_but_never_a_live_line():
    import time

    replay = _frames_every(200, 1_000_000_000)  # 200 s of capture time at once: faster than real time
    undrained = TuiSink(max_backlog=20)
    for f in replay:  # nobody drains it (yet): a pipeline collecting frames never waits
        undrained.frame(f)
    assert undrained.backlog == 200
    sink = TuiSink(max_backlog=20)
    sink.drain()  # a UI is there
    pusher = threading.Thread(target=lambda: [sink.frame(f) for f in replay], daemon=True)
    pusher.start()
    time.sleep(0.2)
    assert pusher.is_alive() and sink.backlog == 20  # waits for the UI with the backlog full
    got = []
    while pusher.is_alive() or sink.backlog:
        got += sink.drain(7)
        time.sleep(0.001)
    assert [f.index for f in got] == list(range(200))

    stuck = TuiSink(max_backlog=20)
    stuck.drain()
    pusher = threading.Thread(target=lambda: [stuck.frame(f) for f in replay], daemon=True)
    pusher.start()
    time.sleep(0.1)
    stuck.release()  # the App quits: the capture must not hang on a sink nobody drains
    pusher.join(2)
    assert not pusher.is_alive() and stuck.backlog == 200

    live = TuiSink(max_backlog=5)
    for f in _frames_every(50, 1000):  # capture time no faster than the wall clock
        live.frame(f)
    assert live.backlog == 50


class _FakeClock:
    """A clock that moves only when frames are handed over: `cost` seconds a frame."""

    def __init__(self, cost: float) -> None:
        self.now, self.cost = 0.0, cost

    def __call__(self) -> float:
        return self.now


def test_budgeted_drain_delivers_every_frame_in_order_while_a_capture_pushes():
    """The UI takes frames in for a time budget at a time (issue 11: 5,000 frames a tick kept keys waiting
    for half a second); whatever the budget and the pace of the pusher, every frame arrives once, in order."""
    frames = _frames_every(5000, 1000)
    for cost, budget in ((1e-5, 0.008), (4e-4, 0.008), (0.02, 0.008)):  # fast, slow and slower than a budget
        sink, clock = TuiSink(), _FakeClock(cost)
        got, calls = [], []

        def add(batch, clock=clock, got=got):
            got.extend(batch)
            clock.now += clock.cost * len(batch)

        pusher = threading.Thread(target=lambda sink=sink: [sink.frame(f) for f in frames])
        pusher.start()
        while pusher.is_alive() or sink.backlog:
            t0 = clock.now
            n = sink.drain_into(add, budget_s=budget, clock=clock)
            calls.append((n, clock.now - t0))
        pusher.join()
        assert [f.index for f in got] == list(range(5000))
        # after the first call (cost unknown: a first list of INTAKE_CHUNK frames), a call ends within one
        # frame's cost of its budget (one frame a call when a frame alone takes longer)
        calls = [(n, spent) for n, spent in calls if n][1:]  # (a call may find nothing pushed yet)
        for n, spent in calls:
            assert spent <= budget + cost * 1.001 and n <= max(1, budget / cost + 1), (cost, n, spent)
        # with every frame waiting, a call takes what its budget holds at the cost seen so far
        sink.frames(frames)
        n = sink.drain_into(add, budget_s=budget, clock=clock)
        assert n == 1 if cost > budget else abs(n - budget / cost) <= 1, (cost, n)


def test_budgeted_drain_keeps_limit_and_without_a_budget_is_drain():
    frames = _frames_every(300, 1000)
    sink = TuiSink()
    sink.frames(frames)
    got = []
    assert sink.drain_into(got.extend, limit=20, budget_s=10.0) == 20  # a limit holds with any budget
    assert sink.drain_into(got.extend, limit=50) == 50  # no budget: one list of up to `limit`
    assert sink.drain_into(got.extend) == 230 and sink.drain_into(got.extend) == 0
    assert [f.index for f in got] == list(range(300))


def test_register_blocks_build_the_same_register_watch_as_their_point_dicts():
    """The register book takes a generic decoder's block of values without building its points (the
    fast path of a 125-register poll); the watch is the one the point dicts give, value for value."""
    from decoders.generic.block import RegisterBlock

    from tui_helpers import _decode

    # decoded afresh: the shared frames of replay_frames lose their blocks to any test that reads f.points
    # (test_decoder_writes reads every capture's), and this test runs after them in the full suite
    info, frames, _, _ = _decode.__wrapped__("fast.mcap")
    assert sum(type(f._points) is RegisterBlock for f in frames) > 100
    fast, slow = FrameStore(info.t0_ns), FrameStore(info.t0_ns)
    fast.add(frames)
    for f in frames:
        g = unpack(pack(f))
        if type(f._points) is RegisterBlock:
            g.points = f._points.points()  # the dicts (f itself is shared: reading f.points would change it)
        slow.add([g])

    def watch(store):
        return {k: (rv.name, rv.id, rv.value, rv.raw, rv.eng_unit, rv.text, rv.t_ns, rv.changed_ns, rv.changes,
                    rv.words, list(rv.history.t), list(rv.history.v), list(rv.history.ix))
                for k, rv in store.registers.items()}

    assert len(fast.registers) > 20 and watch(fast) == watch(slow)
