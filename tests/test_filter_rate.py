"""`rate(EXPR) op N/TIME` in the filter language: parsing, and the count over a sliding window of capture time.

The expectations are counted here by brute force over the decoded frames of a simulated capture
(every frame against every other), not with the sliding windows the code keeps.
"""

import pytest
from tui_helpers import replay_frames, store_of

from sniffer.filterlang import Context, Query, parse
from sniffer.filterlang.rate import Rate, parse_per
from sniffer.analysis.flags import F_CRC, F_TIMEOUT, frame_flags
from sniffer.tui.store import FrameStore

S = 1_000_000_000


@pytest.mark.parametrize("text,count,window_s", [
    ("rate(crc) > 5/min", 5, 60), ("rate(crc)>5/min", 5, 60), ("rate(timeout u:3) >= 3/10s", 3, 10),
    ("rate(exc) < 1/h", 1, 3600), ("rate(u:1 or fault) != 0/500ms", 0, 0.5), ("RATE(crc) = 2/2min", 2, 120),
])
def test_a_rate_parses_to_a_count_per_window_and_prints_as_typed(text, count, window_s):
    node = parse(text)
    assert isinstance(node, Rate)
    assert (node.count, node.window_ns) == (count, int(window_s * S))
    assert str(node) == text and str(parse(str(node))) == text


def test_rate_without_parentheses_is_a_word():
    assert str(parse("rate")) == "rate" and not isinstance(parse("rate"), Rate)


def test_parse_per_reads_the_window_from_the_denominator():
    assert parse_per("5/min") == (5, 60 * S)
    assert parse_per("20/10min") == (20, 600 * S)
    assert parse_per("0.5/s") == (0.5, S)
    assert parse_per("7/1.5h") == (7, int(5400 * S))


def _brute(frames, inner_mask, window_ns, op_pass, arrived_only):
    """For each frame: does the count of frames with `inner_mask` in (t - W, t] pass?"""
    out = []
    for i, f in enumerate(frames):
        pool = frames[:i + 1] if arrived_only else frames
        n = sum(1 for g in pool if frame_flags(g) & inner_mask and f.t_ns - window_ns < g.t_ns <= f.t_ns)
        out.append(op_pass(n))
    return out


@pytest.mark.parametrize("text,mask,window_s,op_pass", [
    ("rate(crc) > 2/s", F_CRC, 1, lambda n: n > 2),
    ("rate(crc) >= 1/200ms", F_CRC, 0.2, lambda n: n >= 1),
    ("rate(timeout) < 3/2s", F_TIMEOUT, 2, lambda n: n < 3),
    ("rate(crc) != 0/s", F_CRC, 1, lambda n: n != 0),
])
def test_on_a_stream_each_frame_counts_the_matches_before_it_in_the_window(text, mask, window_s, op_pass):
    info, frames, _ = replay_frames("errors.mcap")
    q = Query(text)
    ctx = Context(info.t0_ns)
    got = [q.matches(f, ctx) for f in frames]
    want = _brute(frames, mask, int(window_s * S), op_pass, arrived_only=True)
    assert got == want
    assert any(got) and not all(got)  # the capture has both: the test can tell


def test_a_rate_counts_every_frame_whatever_the_rest_of_the_filter_says():
    """`u:1 rate(crc) > 1/s`: unit 1's frames while the whole line has more than one CRC error a second
    (the And stops at u:1 for other units, the count must not)."""
    info, frames, _ = replay_frames("errors.mcap")
    q = Query("u:1 rate(crc) > 1/s")
    got = [i for i, f in enumerate(frames) if q.matches(f, Context(info.t0_ns))]
    line = _brute(frames, F_CRC, S, lambda n: n > 1, arrived_only=True)
    want = [i for i, f in enumerate(frames) if f.unit == 1 and line[i]]
    assert got == want and want


@pytest.mark.parametrize("text,mask,window_s,op_pass", [
    ("rate(crc) > 2/s", F_CRC, 1, lambda n: n > 2),
    ("rate(timeout) >= 2/2s", F_TIMEOUT, 2, lambda n: n >= 2),
])
def test_on_a_store_the_rows_count_the_same(text, mask, window_s, op_pass):
    info, frames, _ = replay_frames("errors.mcap")
    store = store_of("errors.mcap")
    got = Query(text).rows(store, len(store))
    want = _brute(frames, mask, int(window_s * S), op_pass, arrived_only=False)
    assert got == [i for i, ok in enumerate(want) if ok]
    # beside a term only the frames decide ("Output frequency" needs the frames): the same rows, and-ed
    both = Query(f'{text} "pair.retry"').rows(store, len(store))
    assert both == [i for i in got if any(a.code == "pair.retry" for a in frames[i].annotations)]


def test_a_store_filtered_by_a_rate_goes_on_counting_the_frames_that_arrive():
    info, frames, _ = replay_frames("errors.mcap")
    half = len(frames) // 2
    store = FrameStore(info.t0_ns)
    store.add(frames[:half])
    store.update_filter(text="rate(crc) > 1/s")
    store.add(frames[half:])
    want = _brute(frames, F_CRC, S, lambda n: n > 1, arrived_only=False)
    assert list(store.view) == [i for i, ok in enumerate(want) if ok]
