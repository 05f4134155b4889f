"""The TUI's store and sink, without Textual."""

import threading

from tui_helpers import replay_frames

from sniffer.tui.filters import filter_expr, parse_filter
from sniffer.tui.model import F_EXC, F_NOISE, F_PROBLEM, F_TIMEOUT, Filter, FrameStore
from sniffer.tui.sink import TuiSink


def store_of(name="errors.mcap") -> FrameStore:
    info, frames, _ = replay_frames(name)
    s = FrameStore(info.t0_ns)
    s.add(frames)
    return s


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

    code = ("import sys, sniffer.tui.model, sniffer.tui.sink, sniffer.tui.filters; "
            "sys.exit(1 if any(m == 'textual' or m.startswith('textual.') for m in sys.modules) else 0)")
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_records_round_trip_into_the_store():
    from sniffer.records import frame_record

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
