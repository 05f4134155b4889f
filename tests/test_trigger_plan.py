"""When trigger windows open, grow and close (sniffer/triggers/plan.py), on synthetic capture times only."""

from sniffer.triggers.plan import Plan

S = 1_000_000_000


def _plan(**kw):
    kw.setdefault("settle_ns", 2 * S)
    return Plan(2, 300 * S, 60 * S, **kw)


def test_a_firing_opens_a_window_from_pre_before_to_post_after():
    p = _plan()
    w, firing = p.match(0, 1000 * S)
    assert firing is not None and (w.start_ns, w.trigger_ns, w.end_ns) == (700 * S, 1000 * S, 1060 * S)
    assert p.advance(1060 * S) == [] and p.advance(1062 * S) == []  # end + settle not passed yet
    done = p.advance(1062 * S + 1)
    assert done == [w] and w.complete and not p.active and p.windows == 1 and p.fired == 1


def test_matches_in_the_window_move_its_end_to_post_after_the_last():
    p = _plan()
    w, _ = p.match(0, 1000 * S)
    p.advance(1030 * S)
    w2, firing = p.match(0, 1030 * S)  # the same rule, not re-armed: extends, does not fire
    assert w2 is w and firing is None and w.end_ns == 1090 * S and w.matches == {0: 2}
    assert p.fired == 1


def test_another_rule_in_the_open_window_joins_it_and_is_recorded():
    p = _plan()
    w, _ = p.match(0, 1000 * S)
    w2, firing = p.match(1, 1010 * S)
    assert w2 is w and firing is not None and [f.rule for f in w.firings] == [0, 1]
    assert w.rules == [0, 1] and w.end_ns == 1070 * S and p.windows == 1 and p.fired == 2


def test_a_window_grows_at_most_max_window_after_its_trigger():
    p = _plan(max_window_ns=120 * S)
    w, _ = p.match(0, 1000 * S)
    for t in range(1010, 1200, 10):  # a fault in every poll
        p.advance(t * S)
        p.match(0, t * S)
    assert w.end_ns == 1120 * S and w.capped
    p.advance(1123 * S)
    assert not p.active
    # the rule matches on, never quiet for post: nothing fires (suppressed), no window opens
    w3, firing = p.match(0, 1200 * S)
    assert w3 is None and firing is None and p.suppressed >= 1
    # quiet for more than post: armed again
    w4, firing = p.match(0, 1261 * S)
    assert firing is not None and w4.n == 2


def test_default_max_window_is_ten_times_post():
    p = _plan()
    assert p.max_window_ns == 600 * S


def test_a_window_that_passed_its_end_takes_late_frames_but_does_not_grow():
    p = _plan()
    w, _ = p.match(0, 1000 * S)
    p.advance(1061 * S)  # past the end, within settle: its raw events are done
    w2, firing = p.match(1, 1059 * S)  # a request that timed out, settled late, inside the span
    assert w2 is w and firing is not None and w.end_ns == 1060 * S


def test_a_match_after_a_window_ended_opens_a_new_one_that_may_overlap_its_pre():
    p = _plan()
    w, _ = p.match(0, 1000 * S)
    p.advance(1100 * S)
    w2, firing = p.match(1, 1100 * S)
    assert w2 is not w and firing is not None and w2.start_ns == 800 * S  # its pre covers the first window


def test_the_capture_ending_inside_a_post_span_leaves_the_window_incomplete():
    p = _plan()
    w, _ = p.match(0, 1000 * S)
    p.advance(1030 * S)
    assert p.finish() == [w] and not w.complete
    p2 = _plan()
    w, _ = p2.match(0, 1000 * S)
    p2.advance(1061 * S)
    assert p2.finish() == [w] and w.complete


def test_zero_pre_and_post():
    p = Plan(1, 0, 0, settle_ns=0)
    w, _ = p.match(0, 5 * S)
    assert (w.start_ns, w.end_ns) == (5 * S, 5 * S)
    assert p.advance(5 * S + 1) == [w]
