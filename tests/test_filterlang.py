"""The filter language (sniffer.filterlang): parser, errors, and its meaning on real decoded frames.

Frames come from the simulator's captures (captures/sim) decoded by the pipeline; each expectation is
worked out here from the frames' own fields and bytes (the Modbus layout read literally), not from the
filter code.  test_tui_model.py checks that the store's column answers equal these per-frame ones.
"""

import pytest
from tui_helpers import replay_frames, touches

from sniffer.filterlang import Context, FilterError, Query, parse, register_ids
from sniffer.filterlang.nodes import And, Compare, Field, Flag, Models, Not, Or, Regs, Roles, Text
from sniffer.tui.filters import filter_expr, parse_filter
from sniffer.tui.store import Filter


def rows(name: str, text: str, ids: bool = False) -> list[int]:
    """Indexes of the frames of a capture passing `text` (frame by frame: Query.matches)."""
    info, frames, registry = replay_frames(name)
    ctx = Context(info.t0_ns, register_ids(registry) if ids else None)
    q = Query(text)
    return [i for i, f in enumerate(frames) if q.matches(f, ctx)]


def where(name: str, pred) -> list[int]:
    return [i for i, f in enumerate(replay_frames(name)[1]) if pred(f)]


def point_values(f, name: str) -> list:
    return [p["value"] for p in f.points if p["name"] == name]


# ---------------------------------------------------------------- parser: every construct
@pytest.mark.parametrize("text,kind", [
    ("reg:2520H", Regs), ("reg:9508", Regs), ("reg:holding[300]..holding[310]", Regs), ("reg:12-00", Regs),
    ('"Output frequency" > 50', Compare), ("2524H >= 50Hz", Compare), ("holding[300] != 7", Compare),
    ("lat>20ms", Field), ("t:10s..20s", Field), ("t:..5s", Field), ("t:30s..", Field), ("u!=9", Field),
    ("fc=0x10", Field), ("u:1,2", Field), ("fc:3,16", Field), ("role:req", Roles), ("model:a510", Models),
    ("err", Flag), ("crc", Flag), ("exc", Flag), ("timeout", Flag), ("fault", Flag), ("noise", Flag),
    ("warn", Flag), ("!u:9", Not), ("not u:9", Not), ("holding[300]", Text), ('"illegal data"', Text),
    ("u:1 fc:3", And), ("u:1 and fc:3", And), ("u:1 && fc:3", And), ("u:1 or u:2", Or), ("u:1 || u:2", Or),
])
def test_each_construct_parses_to_its_term_and_prints_as_typed(text, kind):
    node = parse(text)
    assert isinstance(node, kind)
    assert str(parse(str(node))) == str(node)
    if kind not in (And, Or, Not):
        assert str(node) == text  # a term prints as it was typed (the bar reopens on it)


def test_precedence_not_then_and_then_or():
    n = parse("a or b c")
    assert isinstance(n, Or) and isinstance(n.items[1], And)
    n = parse("a b or c")
    assert isinstance(n, Or) and isinstance(n.items[0], And)
    n = parse("!a b")
    assert isinstance(n, And) and isinstance(n.items[0], Not)
    n = parse("not a or b")
    assert isinstance(n, Or) and isinstance(n.items[0], Not)
    n = parse("(a or b) c")
    assert isinstance(n, And) and isinstance(n.items[0], Or)
    assert str(n) == "(a or b) c"
    n = parse("!(a or b)")
    assert isinstance(n, Not) and isinstance(n.item, Or) and str(n) == "!(a or b)"
    assert str(parse("a (b c)")) == "a b c" and len(parse("a (b c)").items) == 3  # flattened
    assert str(parse("a  AND  b   OR c")) == "a b or c"


def test_keys_values_and_words_are_case_insensitive():
    assert rows("a510.mcap", "U:1 FC:3 ROLE:RSP") == rows("a510.mcap", "u:1 fc:3 role:rsp")
    assert rows("a510.mcap", '"OUTPUT FREQUENCY" > 10') == rows("a510.mcap", '"output frequency" > 10')
    assert rows("a510.mcap", "reg:2520h") == rows("a510.mcap", "reg:2520H") == rows("a510.mcap", "REG:0x2520")


@pytest.mark.parametrize("text,column,says", [
    ("u:", 3, "'u:' needs a value"),
    ("lat>", 5, "'>' needs a value after it"),
    ("u:1 (fc:3", 10, "the '(' at column 5 is not closed"),
    ("u:1)", 4, "')' without its '('"),
    ("foo:1", 1, "unknown key 'foo:'"),
    ("u:999", 3, "a unit is 0..255"),
    ("fc:3,x", 6, "a function code is 0..255, not 'x'"),
    ("role:boss", 6, "unknown role 'boss'"),
    ("reg:foo", 5, "not a register: 'foo'"),
    ("reg:holding[zz]", 13, "not a register number: 'zz'"),
    ("reg:holding[1]..input[5]", 5, "a range within one table"),
    ("t:5s", 3, "t: takes a range"),
    ("t:1s..2parsecs", 8, "unknown time unit 'parsecs'"),
    ("lat>20parsecs", 7, "unknown time unit 'parsecs'"),
    ('u:1 "abc', 5, "the quote \" is not closed"),
    ("> 5", 1, "'>' needs a point name or a field"),
    ("u:1 or", 7, "'or' needs a term after it"),
    ("and u:1", 1, "'and' needs a term before it"),
    ("u:1 or or u:2", 8, "'or' needs a term after it"),
    ("()", 1, "empty parentheses"),
    ('"Output frequency" > OV', 22, "'>' compares numbers; 'OV' is not one"),
    ("lat ~ 5", 5, "'~' compares text; lat is a number"),
    ("u:1 !", 6, "'!' needs a term after it"),
    ('""', 1, "empty quotes"),
    ("u:1>3", 4, "'>' needs a point name or a field"),
    ("rate(crc) > 5", 13, "count per time"),
    ("rate(crc) > 5/", 15, "more than 0"),
    ("rate(crc) > 5/0s", 15, "more than 0"),
    ("rate(crc) > 5/25h", 15, "at most 24h"),
    ("rate(crc) > 5/fortnight", 15, "unknown time unit"),
    ("rate(crc) > x/min", 13, "count per time"),
    ("rate(crc)", 10, "compares with a count"),
    ("rate(crc) ~ 5/min", 11, "compares with a count"),
    ("rate() > 1/s", 5, "needs a filter inside"),
    ("rate(crc > 1/s", 15, "is not closed"),
    ("rate(rate(crc) > 1/s) > 1/s", 6, "a rate inside a rate"),
    ("rate(crc) >", 12, "needs a count per time"),
])
def test_errors_say_what_and_where(text, column, says):
    with pytest.raises(FilterError) as e:
        parse(text)
    assert e.value.pos + 1 == column and says in e.value.msg
    assert str(e.value) == f"filter error at column {column}: {e.value.msg}"
    assert "\n" not in str(e.value) and isinstance(e.value, ValueError)


def test_empty_filter_passes_everything():
    assert parse("") is None and parse("   ") is None
    assert len(rows("errors.mcap", "")) == len(replay_frames("errors.mcap")[1])


@pytest.mark.parametrize("text", [
    'u:1,2 fc:3 role:req err "Output frequency" > 50 lat>20ms',
    "u:1 or fc:16", "u:2 (fc:3 or exc) !noise", 'reg:2520H..2525H t:10s.. model:a510 "fault code" ~ ov',
    "fc:0x10 u:3 holding[8449]", "err", "", "!u:9",
])
def test_the_bar_reopens_on_the_filter_in_force(text):
    """parse_filter splits the plain and-ed u: fc: role: err into the fields the keys toggle; filter_expr
    joins them back: the same filter, and the same text once it is canonical."""
    kw = parse_filter(text)
    again = filter_expr(Filter(**kw))
    assert parse_filter(again) == kw
    assert filter_expr(Filter(**parse_filter(again))) == again


def test_plain_terms_become_the_fields_the_keys_toggle():
    kw = parse_filter('u:1,2 fc:0x10,3 role:req,rsp err crc "bad" (u:7 or lat>5ms)')
    assert kw["units"] == {1, 2} and kw["functions"] == {16, 3} and kw["roles"] == {"request", "response"}
    assert kw["errors_only"] and kw["text"] == 'crc "bad" (u:7 or lat>5ms)'
    assert filter_expr(Filter(units=frozenset({4}), text="u:1 or u:2")) == "u:4 (u:1 or u:2)"


# ---------------------------------------------------------------- meaning on decoded frames
def test_reg_finds_the_requests_and_responses_touching_a_register():
    got = rows("a510.mcap", "reg:2520H")
    want = where("a510.mcap", lambda f: touches(f, 0x2520))
    frames = replay_frames("a510.mcap")[1]
    assert got == want
    roles = {frames[i].role for i in got}
    assert roles == {"request", "response"}
    # the monitor block is read every cycle: its reads and their answers, nothing else
    assert all("2520H" in frames[i].summary or frames[i].role == "response" for i in got)
    assert rows("a510.mcap", "reg:9508") == rows("a510.mcap", "reg:2524H") == where("a510.mcap",
                                                                                   lambda f: touches(f, 9508))
    assert rows("a510.mcap", "reg:2520H..2525H") == where(
        "a510.mcap", lambda f: any(touches(f, a) for a in range(0x2520, 0x2526)))
    assert rows("errors.mcap", "reg:coil[3]") == where("errors.mcap", lambda f: touches(f, 3, "coil"))
    assert rows("errors.mcap", "reg:coil[3]") != rows("errors.mcap", "reg:3")  # input[3] is read too


def test_parameter_ids_name_registers_through_the_models_maps():
    """TDS-V8 reads Un-01.. as one block (0020H..002FH): the read request carries no point, so only the
    model's register map (the registry's ids) says it touches Un-01; the response's points carry the id."""
    frames = replay_frames("tds-v8.mcap")[1]
    by_map = rows("tds-v8.mcap", "reg:Un-01", ids=True)
    by_points = rows("tds-v8.mcap", "reg:Un-01")
    assert {frames[i].role for i in by_map} == {"request", "response"}
    assert {frames[i].role for i in by_points} == {"response"}
    assert set(by_points) < set(by_map)
    assert by_map == where("tds-v8.mcap", lambda f: f.model == "tds-v8" and touches(f, 0x0020))
    # a free word that reads as an id finds the request naming it and the response carrying it
    cn02 = rows("tds-v8.mcap", "Cn-02", ids=True)
    assert {frames[i].summary for i in cn02} >= {"read Cn-02 (1)", "Max. Output Frequency=60.0 Hz"}


def test_a_point_compared_with_a_value():
    frames = replay_frames("a510.mcap")[1]
    got = rows("a510.mcap", '"Output frequency" > 30')  # the simulated drives run up to 32.5 Hz
    want = where("a510.mcap", lambda f: any(v > 30 for v in point_values(f, "Output frequency")))
    having = where("a510.mcap", lambda f: point_values(f, "Output frequency"))
    assert got == want and 0 < len(got) < len(having)
    assert rows("a510.mcap", '"Output frequency" >= 30Hz') == where(
        "a510.mcap", lambda f: any(v >= 30 for v in point_values(f, "Output frequency")))
    assert rows("a510.mcap", '"Output frequency" > 30V') == []  # the point's unit is Hz
    assert rows("a510.mcap", "2524H > 30") == got == rows("a510.mcap", "9508 > 30")  # by register
    eq = rows("a510.mcap", '"Output frequency" = 0')
    ne = rows("a510.mcap", '"Output frequency" != 0')
    assert sorted(eq + ne) == having and eq and ne  # != needs the point: requests pass neither
    for op, test in (("<", lambda v: v < 20), ("<=", lambda v: v <= 20), ("==", lambda v: v == 20)):
        assert rows("a510.mcap", f'"output frequency" {op} 20') == where(
            "a510.mcap", lambda f, t=test: any(t(v) for v in point_values(f, "Output frequency")))
    assert all(frames[i].role == "response" for i in got)


def test_text_values_compare_with_the_points_text_and_mnemonic():
    fault = "Error description (fault code)"
    ov = rows("a510.mcap", f'"{fault}" = OV')
    assert ov and ov == where("a510.mcap", lambda f: any(
        p["name"] == fault and p.get("text", "").startswith("OV — ") for p in f.points))
    assert rows("a510.mcap", f'"{fault}" = "no fault"') == where("a510.mcap", lambda f: any(
        p["name"] == fault and p.get("text") == "No fault" for p in f.points))
    running = rows("a510.mcap", '"State signal (status word)" ~ "Operation=Run"')
    assert running == where("a510.mcap", lambda f: any(
        p["name"] == "State signal (status word)" and "Operation=Run" in p.get("text", "") for p in f.points))
    assert 0 < len(running) < len(rows("a510.mcap", '"State signal (status word)" ~ operation'))


def test_latency_and_time():
    info, frames, _ = replay_frames("a510.mcap")
    assert rows("a510.mcap", "lat>20ms") == where(
        "a510.mcap", lambda f: f.latency_ms is not None and f.latency_ms > 20)
    assert rows("a510.mcap", "lat>0.02s") == rows("a510.mcap", "lat>20ms") == rows("a510.mcap", "lat>20000us")
    assert rows("a510.mcap", "lat:5..10") == where(
        "a510.mcap", lambda f: f.latency_ms is not None and 5 <= f.latency_ms <= 10)
    t = [(f.t_ns - info.t0_ns) / 1e9 for f in frames]  # a 10 s capture
    assert rows("a510.mcap", "t:2s..4s") == [i for i, x in enumerate(t) if 2 <= x <= 4] != []
    assert rows("a510.mcap", "t:..1.5s") == [i for i, x in enumerate(t) if x <= 1.5] != []
    assert rows("a510.mcap", "t:8s..") == [i for i, x in enumerate(t) if x >= 8] != []
    assert rows("a510.mcap", "t>=8") == rows("a510.mcap", "t:8s..")
    assert rows("a510.mcap", "t:2000ms..4s") == rows("a510.mcap", "t:2s..4s")


def test_logic_negation_and_the_existing_terms():
    n = len(replay_frames("errors.mcap")[1])
    u9 = set(rows("errors.mcap", "u:9"))
    assert u9 and set(rows("errors.mcap", "!u:9")) == set(range(n)) - u9 == set(rows("errors.mcap", "not u:9"))
    u1, u2 = set(rows("errors.mcap", "u:1")), set(rows("errors.mcap", "u:2"))
    fc3 = set(rows("errors.mcap", "fc:3"))
    assert set(rows("errors.mcap", "u:1 fc:3 or u:2")) == (u1 & fc3) | u2
    assert set(rows("errors.mcap", "u:1 (fc:3 or u:2)")) == u1 & (fc3 | u2)
    assert set(rows("errors.mcap", "u:1 and not fc:3")) == u1 - fc3
    assert rows("errors.mcap", "u:1,2") == where("errors.mcap", lambda f: f.unit in (1, 2))
    assert rows("errors.mcap", "fc:3,16") == where("errors.mcap", lambda f: f.function is not None
                                                   and f.function & 0x7F in (3, 16))
    assert rows("errors.mcap", "role:req") == where("errors.mcap", lambda f: f.role == "request")
    assert rows("errors.mcap", "u!=9") == where("errors.mcap", lambda f: f.unit is not None and f.unit != 9)


def test_flags():
    assert rows("errors.mcap", "crc") == where("errors.mcap", lambda f: f.crc_ok is False) != []
    assert rows("errors.mcap", "exc") == where("errors.mcap", lambda f: bool(f.exception)) != []
    assert rows("errors.mcap", "noise") == where("errors.mcap", lambda f: f.protocol == "noise") != []
    assert rows("errors.mcap", "timeout") == where("errors.mcap", lambda f: any(
        a.code in ("pair.timeout", "pair.no_response") for a in f.annotations)) != []
    assert rows("a510.mcap", "fault") == where("a510.mcap", lambda f: any(
        a.code in ("model.fault", "model.alarm") for a in f.annotations)) != []
    assert rows("errors.mcap", "err") == where("errors.mcap", lambda f: f.crc_ok is False or f.exception
                                               or f.protocol == "noise" or any(a.severity in ("error", "warning")
                                                                               for a in f.annotations))
    assert rows("a510.mcap", "model:a510") == where("a510.mcap", lambda f: f.model == "a510") != []
    assert rows("a510.mcap", "model:generic") == []


# ---------------------------------------------------------------- free text
def test_free_text_finds_a_register_beyond_the_shortened_summary(stress_mcap):
    """Issue 11: `holding[300]` found nothing although register 300 is read every cycle: the summary names
    the first 6 of 125 registers.  Free text now matches registers in the notations people type."""
    frames = replay_frames(stress_mcap)[1]
    want = where(stress_mcap, lambda f: touches(f, 300))
    assert len(want) > 20 and not any("holding[300]" in f.summary for f in frames)
    assert rows(stress_mcap, "holding[300]") == want
    for word in ("012CH", "0x12c", "12ch"):
        assert rows(stress_mcap, word) == want
    assert set(rows(stress_mcap, "300")) >= set(want)  # and the frames with "300" in their text or hex
    assert rows(stress_mcap, '"holding[300]"') == []  # quoted: text only, and the generic names are not text


def test_free_text_searches_every_point_name_unit_and_text():
    frames = replay_frames("a510.mcap")[1]
    got = rows("a510.mcap", '"output current"')
    assert got == where("a510.mcap", lambda f: any(p["name"] == "Output current" for p in f.points)
                        or "output current" in f.summary.lower())
    assert any("Output current" not in frames[i].summary for i in got)  # beyond the summary's six points
    assert set(rows("a510.mcap", "hz")) >= set(where("a510.mcap", lambda f: any(p.get("unit") == "Hz"
                                                                               for p in f.points)))
    assert rows("a510.mcap", '"heatsink overheat"') == where("a510.mcap", lambda f: any(
        "Heatsink overheat" in (p.get("text") or "") for p in f.points) or any(
        "Heatsink overheat" in a.detail for a in f.annotations)) != []
    assert rows("errors.mcap", '"illegal data address"') == where(
        "errors.mcap", lambda f: (f.exception or {}).get("name") == "ILLEGAL DATA ADDRESS") != []
    assert rows("errors.mcap", "pair.no_response") == where(
        "errors.mcap", lambda f: any(a.code == "pair.no_response" for a in f.annotations)) != []
    assert rows("errors.mcap", "request") == where("errors.mcap", lambda f: f.role == "request"
                                                   or "request" in f.summary.lower()
                                                   or any("request" in a.detail.lower() for a in f.annotations))


@pytest.mark.parametrize("name", ["a510.mcap", "a510-ascii.mcap", "pd-series-ascii.mcap", "tds-v8.mcap"])
def test_an_arriving_frame_and_a_frame_from_its_record_pass_alike(name):
    """An attached viewer rebuilds frames from their JSON records (ADU from the raw bytes, RTU or ASCII):
    the filter says the same of them."""
    from sniffer.formats.records import frame_record
    from sniffer.tui.store import frame_from_record

    info, frames, registry = replay_frames(name)
    ctx = Context(info.t0_ns, register_ids(registry))
    again = [frame_from_record(frame_record(f, info.t0_ns), info.t0_ns) for f in frames]
    assert [f.adu for f in again] == [f.adu for f in frames]
    for text in ("reg:2520H", "reg:input[1]", "reg:Un-01", '"Output frequency" > 30', "lat>10ms", "t:2s..5s",
                 "fault", '"no fault"', "0x2524", "role:req reg:0..0xFFFF"):
        q = Query(text)
        assert [q.matches(f, ctx) for f in frames] == [q.matches(f, ctx) for f in again]


def test_a510_parameter_12_00_by_its_id():
    """12-00 is the A510's one 32-bit parameter, at 2510H (high word) and 2511H (manual 1.0.3 l.1024): a read
    of it, decoded by the real pipeline, is found by reg:12-00 and by the free word 12-00."""
    from helpers import bursts, fr, run_events

    from decoders.registry import default_registry
    from sniffer.line import LineSettings

    line = LineSettings(19200, "N", 1)
    frames = run_events(bursts([fr("010325100002"), fr("0103040001E240")], line), line, devices={1: "a510"})
    req, rsp = frames
    assert rsp.points[0]["id"] == "12-00" and rsp.points[0]["value"] == 123456 and not req.points
    ids = register_ids(default_registry({1: "a510"}))
    assert ("a510", None, 0x2510, 0x2512) in ids["12-00"]
    with_ids, without = Context(0, ids), Context(0)
    for text, request in (("reg:12-00", True), ("12-00", True), ("reg:2511H", True),
                          ('"Parameter 12-00" = 123456', False), ("12-00 >= 100000", False)):
        assert [Query(text).matches(f, with_ids) for f in frames] == [request, True], text  # a value: the response
    assert [Query("reg:12-00").matches(f, without) for f in frames] == [False, True]  # by the point's id only
