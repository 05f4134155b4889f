"""Several links on one timeline, without ports: LinkPipelines on synthetic events, the MCAP's link
field, the bus file's [[links]], the flags (capture/links.py, capture/settings.py, capture/busfile.py)."""

from __future__ import annotations

import pytest
from helpers import ListSink, bursts, fr, frames_of

from sniffer.capture.busfile import BusFileError, load_bus_file
from sniffer.cli import build_parser
from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.line import LineSettings, SettingsError
from sniffer.formats.mcap.format import decode_event, encode_event
from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.capture.settings import MASTER, SLAVES, LinkPlan
from sniffer.formats.text import TextSink
from sniffer.sources.files import FileSource

LINE = LineSettings(19200, "E", 1)
READ_A = fr("010300000002")
RSP_A = fr("01030400010002")
READ_B = fr("010400100001")
RSP_B = fr("0104020007")


def _on(link: str, chunks, channel: str = "") -> list[Chunk]:
    return [Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, channel, link) for c in chunks]


def _interleaved(a: list[Chunk], b: list[Chunk]) -> list[Chunk]:
    """Per-byte chunks of two links merged by time, one byte at a time (as close as two lines get)."""
    def split(chunks):
        return [Chunk(t, bytes((x,)), (t,), (), c.channel, c.link) for c in chunks for t, x in zip(c.byte_t_ns, c.data)]

    return sorted(split(a) + split(b), key=lambda c: c.t_ns)


def _info(*names, tap=()):
    return CaptureInfo(baud=LINE.baud, parity="E", links=[
        {"name": n, "ports": [f"/dev/{n}"], "tap": n in tap, "baud": LINE.baud, "parity": "E"} for n in names])


def _run(info, events, spec=None, sinks=()):
    sink = ListSink()
    session = Session(spec or CaptureSpec(), EventSource(info, events), [sink, *sinks])
    session.run()
    return session, sink.records


def test_bytes_of_two_links_never_glue():
    a = _on("A", bursts([READ_A, RSP_A, READ_A, RSP_A], LINE))
    b = _on("B", bursts([READ_B, RSP_B, READ_B, RSP_B], LINE, t0=LINE.char_ns // 2))  # byte by byte between A's
    session, recs = _run(_info("A", "B"), _interleaved(a, b))
    for link, want in (("A", [READ_A, RSP_A] * 2), ("B", [READ_B, RSP_B] * 2)):
        got = [r for r in recs if r["link"] == link]
        assert [r["raw"] for r in got] == want and all(r["crc_ok"] for r in got)
        assert [r["role"] for r in got] == ["request", "response"] * 2
    assert sorted(r["index"] for r in recs) == list(range(8))  # one capture-wide numbering
    assert session.frames_out == 8 and session.bytes_in == sum(len(bytes.fromhex(h)) for h in
                                                               [READ_A, RSP_A, READ_B, RSP_B] * 2)


def test_each_link_decodes_with_its_own_units_and_settings(tmp_path):
    bus = tmp_path / "plant.toml"
    bus.write_text('[units]\n1 = "a510"\n\n[[links]]\nname = "A"\nport = "/dev/a"\n\n'
                   '[[links]]\nname = "B"\nport = "/dev/b"\nunits = { 1 = "tds-v8" }\n')
    spec = CaptureSpec.of(bus_file=str(bus))
    a = _on("A", bursts([READ_A, RSP_A], LINE))
    b = _on("B", bursts([READ_A, RSP_A], LINE, t0=10**6))
    session, recs = _run(_info("A", "B"), a + b, spec)
    assert {r["link"]: r["model"] for r in recs} == {"A": "a510", "B": "tds-v8"}
    assert [x["devices"] for x in session.info.links] == [{"1": "a510"}, {"1": "tds-v8"}]  # recorded
    assert set(session.pipeline.registries) == {"A", "B"}
    assert session.pipeline.registries["A"] is not session.pipeline.registries["B"]


def test_a_broadcast_answer_is_found_across_other_links_frames():
    """The pairer's "frame just before" is its own line's, not index - 1 (another link's frame can be between)."""
    bc = _on("A", bursts([fr("000600010055")], LINE))
    other = _on("B", bursts([READ_B], LINE, t0=bc[-1].t_ns + 3 * LINE.char_ns))
    echo = _on("A", bursts([fr("030600010055")], LINE, t0=other[-1].t_ns + 20 * LINE.char_ns))
    _, recs = _run(_info("A", "B"), bc + [Tick(other[0].t_ns - 1, "A")] + other + echo)
    answer = next(r for r in recs if r["link"] == "A" and r["unit"] == 3)
    assert [a["code"] for a in answer["annotations"]][:1] == ["pair.broadcast_response"]


def test_a_tapped_link_takes_the_role_from_the_wire():
    # 06 (write single register) is the same bytes both ways: only the wire tells request from echo
    # (a retry the unit did not answer, then the answer to the second: on one wire the retry looks like the echo)
    write = fr("010600010055")
    chunks = (_on("T", bursts([write, write], LINE, gap_chars=40), MASTER)
              + _on("T", bursts([write], LINE, t0=10**7), SLAVES))
    _, recs = _run(_info("T", tap=("T",)), chunks)
    assert [(r["channel"], r["role"]) for r in recs] == [(MASTER, "request"), (MASTER, "request"), (SLAVES, "response")]
    assert recs[2]["pair"] == recs[1]["index"]
    assert "pair.retry" in [a["code"] for a in recs[1]["annotations"]]


def test_text_has_a_link_column_only_with_several_links(tmp_path):
    import io

    out = io.StringIO()
    _run(_info("drives", "B"), _on("B", bursts([READ_B, RSP_B], LINE)), sinks=[TextSink(out)])
    assert [line.split()[1] for line in out.getvalue().splitlines()] == ["B", "B"]
    one = io.StringIO()
    info = CaptureInfo(baud=LINE.baud, parity="E")
    Session(CaptureSpec(), EventSource(info, bursts([READ_B, RSP_B], LINE)), [TextSink(one)]).run()
    assert [line.split()[1] for line in one.getvalue().splitlines()] == ["->REQ", "<-RSP"]


def test_raw_events_carry_their_link_and_one_line_files_do_not_change():
    for ev in (Chunk(5, b"\x01\x02", None, (), SLAVES, "pumps"), Tick(7, "pumps"), Gap(1, 9, "port lost", "pumps")):
        assert decode_event(encode_event(ev)) == ev
    plain = encode_event(Chunk(5, b"\x01", None, (), ""))
    assert b"link" not in plain and decode_event(plain).link == ""
    # a live read's unseen time, kept only where there is one
    live = Chunk(9_000_000, b"\x01\x03", None, (), "", "", 4_250_000)
    assert decode_event(encode_event(live)) == live and b"unseen_ns" not in plain
    assert "links" not in CaptureInfo().to_dict()
    info = CaptureInfo.from_dict(_info("A").to_dict())
    assert info.links[0]["name"] == "A"


def test_bytes_of_a_link_the_capture_does_not_list_end_it_with_one_line():
    session, recs = _run(_info("A", "B"), _on("C", bursts([READ_A], LINE)))
    assert "link 'C' the capture does not list" in session.error and recs == []


def test_flags_make_links_and_serve_gets_them_back():
    args = build_parser().parse_args(["live", "/dev/ttyUSB0", "/dev/ttyUSB1", "--tap", "/dev/a/ttyS0", "/dev/b/ttyS0",
                                      "--baud", "9600"])
    spec = CaptureSpec.from_args(args)
    assert spec.links == (LinkPlan("ttyUSB0", ("/dev/ttyUSB0",)), LinkPlan("ttyUSB1", ("/dev/ttyUSB1",)),
                          LinkPlan("ttyS0+ttyS0", ("/dev/a/ttyS0", "/dev/b/ttyS0"), True))
    assert spec.links[2].channels == (MASTER, SLAVES)
    assert CaptureSpec.decode(spec.encode()) == spec
    one = CaptureSpec.from_args(build_parser().parse_args(["live", "/dev/ttyUSB0"]))
    assert one.links == () and one.port == "/dev/ttyUSB0"  # one port: a plain line, as before
    twin = CaptureSpec.from_args(build_parser().parse_args(["live", "/dev/a/ttyS0", "/dev/b/ttyS0"]))
    assert [p.name for p in twin.links] == ["/dev/a/ttyS0", "/dev/b/ttyS0"]  # clashing names: the paths


def test_bus_file_links(tmp_path):
    bus = tmp_path / "plant.toml"
    bus.write_text('[serial]\nbaud = 19200\n\n[[links]]\nname = "drives"\nport = "/dev/ttyUSB0"\nparity = "E"\n'
                   'units = { 2 = "a510" }\ntimeouts_ms = { 2 = 250 }\n\n'
                   '[[links]]\nname = "pumps"\ntap = ["/dev/ttyUSB1", "/dev/ttyUSB2"]\nbaud = 9600\n')
    b = load_bus_file(str(bus))
    assert [(x.name, x.ports, x.tap, x.baud, x.parity) for x in b.links] == [
        ("drives", ("/dev/ttyUSB0",), False, None, "E"), ("pumps", ("/dev/ttyUSB1", "/dev/ttyUSB2"), True, 9600, None)]
    spec = CaptureSpec.from_args(build_parser().parse_args(["live", "--bus", str(bus)]))
    drives = spec.resolve_link("drives")
    assert (drives.line.baud, drives.line.parity, drives.devices, drives.unit_timeouts) == \
        (19200, "E", {2: "a510"}, {2: 250.0})  # [serial] is every link's default
    assert spec.resolve_link("pumps").line.baud == 9600
    with pytest.raises(SettingsError, match="no ports on the command line"):
        CaptureSpec.from_args(build_parser().parse_args(["live", "/dev/ttyUSB0", "--bus", str(bus)]))


@pytest.mark.parametrize("text, message", [
    ('[[links]]\nport = "/dev/a"\n', "needs a name"),
    ('[[links]]\nname = "a"\n', "needs a port"),
    ('[[links]]\nname = "a"\nport = "/dev/a"\ntap = ["/dev/b", "/dev/c"]\n', "needs a port"),
    ('[[links]]\nname = "a"\ntap = ["/dev/b"]\n', "tap must be two device paths"),
    ('[[links]]\nname = "a"\nport = "/dev/a"\nbuad = 9600\n', "unknown keys"),
    ('[[links]]\nname = "a"\nport = "/dev/a"\nparity = "X"\n', "[[links]] a parity"),
    ('[[links]]\nname = "a"\nport = "/dev/a"\nunits = { 1 = 5 }\n', "[[links]] a [units] 1"),
    ('[[links]]\nname = "a"\nport = "/dev/a"\n[[links]]\nname = "a"\nport = "/dev/b"\n', "name 'a' given twice"),
    ('[[links]]\nname = "a"\nport = "/dev/a"\n[[links]]\nname = "b"\nport = "/dev/a"\n', "port '/dev/a' given twice"),
    ('links = 3\n', "links must be tables"),
])
def test_bus_file_link_errors_are_one_line(tmp_path, text, message):
    bus = tmp_path / "bad.toml"
    bus.write_text(text)
    with pytest.raises(BusFileError) as e:
        load_bus_file(str(bus))
    assert message in str(e.value) and "\n" not in str(e.value)


def test_trigger_windows_start_every_link_at_its_own_quiet_point(tmp_path):
    """Two links never quiet at once (a request is always waiting on one of them): a window starts each
    link where that link was quiet, so it replays without answers cut off from their requests."""
    from sniffer.triggers import TriggerSpec

    ms = 1_000_000
    req, rsp, exc = (bytes.fromhex(fr(h)) for h in ("010300000001", "0103020007", "018302"))

    def burst(t, data, link):
        return Chunk(t, data, tuple(t + i * LINE.char_ns for i in range(len(data))), (), "", link)

    events = []
    for k in range(40):
        t = k * 100 * ms
        for link, off in (("a", 0), ("b", 50 * ms)):  # each answers 60 ms after its request
            events += [burst(t + off, req, link), Tick(t + off + 20 * ms, link),
                       burst(t + off + 60 * ms, exc if (link, k) == ("b", 25) else rsp, link),
                       Tick(t + off + 80 * ms, link)]
    events.sort(key=lambda e: e.t_ns)
    spec = CaptureSpec(trigger=TriggerSpec(("link:b exc",), windows=str(tmp_path), pre_s=0.52, post_s=0.3))
    info = _info("a", "b")
    info.time_source, info.wall_anchor_ns = "byte", 1_764_000_000 * 10**9
    session, recs = _run(info, events, spec)
    assert session.error is None
    (window,) = sorted(tmp_path.glob("*.mcap"))
    replay = ListSink()
    Session(CaptureSpec(), FileSource(str(window)), [replay]).run()
    got = replay.records
    assert {r["link"] for r in got} == {"a", "b"}
    assert not any(a["code"] == "pair.orphan_response" for r in got for a in r["annotations"])
    def keys(records):
        return {(r["link"], r["t"], r["raw"]) for r in records}

    assert keys(frames_of(window)) <= keys(recs)
    assert [r["role"] for r in got if r["link"] == "a"][:1] == ["request"]
