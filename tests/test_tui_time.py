"""The frame list's time bases, Δt, go-to parsing and the columns that fit a width: without Textual."""

from datetime import datetime, timedelta, timezone

import pytest
from tui_helpers import replay_frames, store_of

from sniffer.tui.framelist import MIN_SUMMARY, fit_columns, format_row
from sniffer.tui.goto import Target, nearest_shown, parse_goto, resolve
from sniffer.tui.store import FrameStore
from sniffer.tui.timebase import REF, REL, WALL, TimeBase, delta_text, parse_duration

S = 1_000_000_000
PLUS2 = timezone(timedelta(hours=2))
# the capture started 2024-05-01 19:22:00.000 at UTC+2 (17:22 UTC); its own clock read 5 s then
START = datetime(2024, 5, 1, 19, 22, tzinfo=PLUS2)
T0 = 5 * S


def wall_base(**kw) -> TimeBase:
    anchor = int((START - datetime(1970, 1, 1, tzinfo=timezone.utc)).total_seconds()) * S
    return TimeBase(T0, anchor, tz=PLUS2, **kw)


def test_relative_times_are_exact_microseconds_from_integer_ns():
    tb = TimeBase(T0)
    assert tb.text(T0) == "0.000000"
    assert tb.text(T0 + 345_504_499) == "0.345504" and tb.text(T0 + 345_504_500) == "0.345505"  # rounded
    assert tb.text(T0 + 3 * 86_400 * S + 1_000) == "259200.000001"  # days in: no float drift
    assert tb.full_text(T0 + S // 2) == "0.500000s since the start"
    assert tb.title() == "time (s)" and tb.describe() == "time: since the capture's start"


def test_wall_clock_in_the_viewers_zone_with_the_date_in_the_header():
    tb = wall_base(mode=WALL)
    t = T0 + 61 * S + 250_123_456  # 19:23:01.250123456
    assert tb.text(t) == "19:23:01.250"
    assert tb.full_text(t) == "2024-05-01 19:23:01.250123 UTC+02:00 (wall clock)"
    assert tb.describe() == "time: wall clock, 2024-05-01 UTC+02:00"
    assert tb.title() == "wall clock" and tb.width(T0, t) == len("19:23:01.250")
    utc = wall_base(mode=WALL)
    utc.tz = timezone.utc
    assert utc.text(t) == "17:23:01.250"
    assert tb.t_of_wall(tb.wall_datetime(t)) == t - 456  # back, to the microsecond


def test_times_from_a_reference_are_signed():
    tb = TimeBase(T0)
    assert tb.toggle_reference(7, T0 + 2 * S, 42) is True
    assert tb.mode == REF and tb.title() == "from #42" and tb.describe() == "time: from the reference #42"
    assert tb.text(T0 + S) == "-1.000000" and tb.text(T0 + 3 * S) == "+1.000000" and tb.text(T0 + 2 * S) == "+0.000000"
    assert tb.full_text(T0 + 2 * S + 1_500_000) == "+0.001500s from the reference #42"
    assert tb.width(T0, T0 + 12 * S) == len("+10.000000")


def test_t_cycles_the_bases_on_offer_and_T_on_the_reference_clears_it():
    rel_only = TimeBase(T0)
    assert rel_only.modes() == [REL] and rel_only.cycle() is None and rel_only.mode == REL
    tb = wall_base()
    assert [tb.cycle(), tb.cycle()] == [WALL, REL]
    v = tb.version
    tb.toggle_reference(3, T0 + S, 3)
    assert tb.mode == REF and tb.version > v
    assert [tb.cycle(), tb.cycle(), tb.cycle()] == [REL, WALL, REF]
    tb.toggle_reference(9, T0 + 2 * S, 9)  # another frame: the reference moves
    assert (tb.ref_row, tb.ref_index, tb.mode) == (9, 9, REF)
    assert tb.toggle_reference(9, T0 + 2 * S, 9) is False  # the same frame: cleared, back to since the start
    assert tb.ref_row is None and tb.mode == REL and tb.modes() == [REL, WALL]
    tb.mode = WALL
    tb.toggle_reference(1, T0, 1)
    tb.mode = WALL
    tb.toggle_reference(1, T0, 1)  # clearing while the wall clock shows keeps the wall clock
    assert tb.mode == WALL


def test_delta_text_is_short():
    assert delta_text(270_000) == "0.27ms"
    assert delta_text(45_904_000) == "45.90ms"
    assert delta_text(-1_150_000) == "-1.15ms"
    assert delta_text(1_250_000_000) == "1.250s"
    assert delta_text(150 * S) == "150s"
    assert delta_text(999_999_999) == "1.000s" and delta_text(-999_000_000) == "-999.0ms"
    assert max(len(delta_text(ns)) for ns in (999_999_999, -999_999_999, 99_999 * S, 99 * S + S // 2, -99 * S)) <= 8


@pytest.mark.parametrize("text,ns", [("12.5s", 12_500_000_000), ("350ms", 350_000_000), ("20us", 20_000),
                                     ("20µs", 20_000), ("1.5min", 90 * S), ("2h", 7200 * S), ("-0.5s", -S // 2),
                                     (".25 s", S // 4), ("0.0000000015s", 2), ("7ns", 7)])
def test_parse_duration(text, ns):
    assert parse_duration(text) == ns


@pytest.mark.parametrize("text", ["12", "abc", "1e3s", "", "12.5 parsecs", "s", "1.2.3s", "99999999999h"])
def test_parse_duration_refuses(text):
    with pytest.raises(ValueError):
        parse_duration(text)


def test_goto_parses_frame_numbers_and_times_in_the_base_shown():
    tb = wall_base()
    assert parse_goto("1234", tb) == Target(index=1234, text="1234")
    assert parse_goto(" #1234 ", tb).index == 1234
    assert parse_goto("12.5s", tb).t_ns == T0 + 12_500_000_000
    assert parse_goto("12.5", tb).t_ns == T0 + 12_500_000_000  # a decimal point means seconds
    assert parse_goto("350ms", tb).t_ns == T0 + 350_000_000
    assert parse_goto("19:22:01.250", tb).t_ns == T0 + 1_250_000_000
    assert parse_goto("19:23", tb).t_ns == T0 + 60 * S
    assert parse_goto("2024-05-01 19:22:03.5", tb).t_ns == T0 + 3_500_000_000
    tb.toggle_reference(4, T0 + 10 * S, 4)  # times shown from the reference: durations count from it
    assert parse_goto("-0.5s", tb).t_ns == T0 + 9_500_000_000
    assert parse_goto("19:22:01.250", tb).t_ns == T0 + 1_250_000_000  # the wall clock is the wall clock


def test_goto_a_time_of_day_after_midnight_in_a_capture_that_ran_past_it():
    tb = wall_base()
    two_days = T0 + 36 * 3600 * S
    assert parse_goto("01:00", tb, last_t_ns=two_days).t_ns == T0 + (5 * 3600 + 38 * 60) * S  # the next day
    assert parse_goto("01:00", tb, last_t_ns=T0 + 60 * S).t_ns < T0  # a short capture: before its start


@pytest.mark.parametrize("text,says", [("abc", "is not a frame number or a time"), ("#12.5", "not a frame number"),
                                       ("12", None), ("25:00", "not a wall-clock time"),
                                       ("19:61", "not a wall-clock time"), ("12 s x", "not a frame number")])
def test_goto_bad_input_is_one_sentence(text, says):
    if says is None:
        assert parse_goto(text, wall_base()).index == 12
        return
    with pytest.raises(ValueError, match=says) as e:
        parse_goto(text, wall_base())
    assert "\n" not in str(e.value)


def test_goto_wall_clock_without_a_known_start_says_so():
    with pytest.raises(ValueError, match="no wall-clock start"):
        parse_goto("19:22:01", TimeBase(T0))


def test_nearest_shown_row():
    view = [2, 5, 9]
    assert [nearest_shown(view, r) for r in (0, 2, 3, 4, 7, 8, 20)] == [2, 2, 2, 5, 9, 9, 9]
    assert nearest_shown(view, 7) == 9  # a tie: the later one
    assert nearest_shown([], 3) is None


def test_resolve_a_frame_number_a_time_and_a_hidden_frame():
    s = store_of()
    first, last = s.frames[0].index, s.frames[-1].index
    assert resolve(s, Target(index=17)) == (s.row_of[17], None)
    with pytest.raises(ValueError, match=f"no frame #99999 here \\(frames #{first}..#{last}\\)"):
        resolve(s, Target(index=99999))
    t = s.t_ns[40] - 1  # just before frame row 40: lands on it
    assert resolve(s, Target(t_ns=t, text="x")) == (40, None)
    assert resolve(s, Target(t_ns=s.t_ns[40], text="x")) == (40, None)
    with pytest.raises(ValueError, match="no frame at or after"):
        resolve(s, Target(t_ns=s.last_t_ns + 1, text="x"))
    s.update_filter(units=frozenset({2}))
    hidden = next(r for r in range(30, len(s)) if s.pos_of_row(r) is None)
    row, note = resolve(s, Target(index=s.frames[hidden].index))
    assert row == nearest_shown(s.view, hidden) and s.frames[row].unit == 2
    assert note == f"#{s.frames[hidden].index} is hidden by the filter: at #{s.frames[row].index}, " \
                   "the nearest shown frame"
    row, note = resolve(s, Target(t_ns=s.t_ns[hidden], text="1.5s"))
    assert row == nearest_shown(s.view, hidden)
    assert note.startswith(f"the first frame at or after 1.5s (#{s.frames[hidden].index}) is hidden by the filter")
    s.update_filter(units=frozenset({99}))
    with pytest.raises(ValueError, match="nothing is shown"):
        resolve(s, Target(index=17))


def test_resolve_past_a_paused_view():
    s = FrameStore(replay_frames()[0].t0_ns)
    frames = replay_frames()[1]
    s.add(frames[:50])
    s.pause(True)
    s.add(frames[50:])
    row, note = resolve(s, Target(index=frames[80].index))
    assert row == 49 and note == f"#{frames[80].index} is the paused view ends before it: at #{frames[49].index}, " \
                                 "the nearest shown frame"


def test_columns_fit_the_width_and_keep_the_summary():
    s = store_of()
    tb = s.time
    span = (s.t_ns[0], s.last_t_ns, s.frames[-1].index)
    wide = fit_columns(138, tb, *span)
    assert [c.key for c in wide.columns] == ["mark", "time", "dt", "dir", "unit", "model", "fc", "pair", "lat"]
    narrow = fit_columns(78, tb, *span)  # 80 columns less the scrollbar
    assert narrow.summary >= MIN_SUMMARY and not narrow.has("model") and narrow.has("dt") and narrow.has("lat")
    tb.mode = WALL
    tb.wall_anchor_ns = 1
    wall = fit_columns(78, tb, *span)
    assert wall.summary >= MIN_SUMMARY and wall.has("dt") and not wall.has("fc")
    tb.mode = REL
    big = fit_columns(78, tb, s.t0_ns, s.t0_ns + 5000 * S, 999_999)  # an hour and a half, a million frames
    assert big.summary >= MIN_SUMMARY and big.has("lat") and big.has("pair")
    tiny = fit_columns(40, tb, *span)  # nothing more to drop: the summary gets what is left
    assert [c.key for c in tiny.columns] == ["mark", "time", "dir", "unit", "pair"]


@pytest.mark.parametrize("width", [78, 100, 138])
def test_rows_line_up_under_the_header(width):
    s = store_of()
    tb = s.time
    tb.toggle_reference(10, s.t_ns[10], s.frames[10].index)
    lay = fit_columns(width, tb, s.t_ns[0], s.last_t_ns, s.frames[-1].index)
    head = lay.header
    summary_at = head.index(" summary") + 1
    for row in range(1, 60):
        text = format_row(s.frames[row], s.flags[row], lay, tb, row == 3, row == 10, s.t_ns[row - 1]).plain
        assert len(text) <= width
        assert text[summary_at - 1] == " " and text[summary_at] != " "  # the summary starts under its title
        if row == 10:
            assert "*REF*" in text[:summary_at]
        if lay.has("dt"):
            end = head.index("Δt") + 2
            assert text[:end].rstrip().endswith(delta_text(s.t_ns[row] - s.t_ns[row - 1]))
