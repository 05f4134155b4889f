"""`sniffer report`: the figures the collector gathers (synthetic frames, so each is known), the page the CLI
writes from real captures (every script inline, the counts those of a replay of the same files), several
captures on one axis, several links, --compare.

Bad input: tests/test_report_bad_input.py; what the page looks like in a browser: tests/test_report_chromium.py.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from helpers import decoded

from sniffer.cli import main
from sniffer.codes import Annotation
from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.report import Collector
from sniffer.report.buckets import TimeBuckets
from sniffer.report.polls import Polls
from sniffer.report.timeline import Timeline
from sniffer.capture.settings import CaptureSpec

SIM = Path(__file__).resolve().parent.parent / "captures" / "sim"
MS = 1_000_000


def page_data(path: Path) -> dict:
    text = path.read_text(encoding="utf-8")
    m = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', text, re.S)
    assert m, "no data block"
    return json.loads(m.group(1).replace("<\\/", "</"))


def cli(capsys, *args) -> tuple[int, list[str]]:
    rc = main([str(a) for a in args])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return rc, [line for line in err.splitlines() if line.strip()]


def left_in(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.suffix in (".html", ".part") or p.name.endswith(".part"))


# ------------------------------------------------------------------ the figures, on synthetic frames
def frame(index, t_ms, unit=1, fc=3, role="request", raw=b"\x01\x03\x00\x00\x00\x01\x84\x0a", **kw) -> Frame:
    t = int(t_ms * MS)
    f = Frame(index, t, t + 5 * MS, raw, "modbus-rtu", unit, fc, crc_ok=kw.pop("crc_ok", True))
    f.role = role
    f.adu = raw[:-2]
    for k, v in kw.items():
        setattr(f, k, v)
    return f


def session_of(info: CaptureInfo, baud: int = 9600) -> SimpleNamespace:
    resolved = CaptureSpec.of(baud=baud).resolve(info)
    return SimpleNamespace(info=info, resolved=resolved, source=SimpleNamespace(path="synthetic.mcap"), spec=None,
                           frames_out=0, bytes_in=0, noise_bytes=0, damage=[], error=None, registry=None)


def test_buckets_merge_keeps_every_count():
    b = TimeBuckets(("n",), n=8, width_ns=10)
    for t in range(0, 1000, 3):  # 334 events over 1000 ns: the width doubles until 8 buckets cover them
        b.cols["n"][b.index(t)] += 1
    assert b.total("n") == 334
    assert b.width == 160 and b.top == 6  # 10 -> 160 ns: 7 buckets of 160 cover 0..999
    d = b.to_dict(end_ns=1000)
    assert d["x"][:3] == [0.0, 160e-9, 320e-9] and sum(d["n"]) == 334
    assert d["span_s"][-1] == pytest.approx(40e-9)  # the last bucket lies partly after the end


def test_poll_period_and_jitter_per_request_type():
    p = Polls()
    gaps = [100, 100, 100, 100, 100, 100, 100, 100, 100, 300]  # one cycle skipped
    t = 0
    for i, g in enumerate([0] + gaps):
        t += g
        p.request(frame(i, t))
    p.request(frame(99, 50, unit=2, raw=b"\x02\x03\x00\x10\x00\x02\xc5\xfd"))
    rows = {r["type"]: r for r in p.to_dict()["rows"]}
    r = rows["u1 fc03 holding 0..0 (1)"]
    assert r["count"] == 11 and r["period_ms"] == 100 and r["max_ms"] == 300 and r["min_ms"] == 100
    assert r["jitter_ms"] == 200  # p95 - p5: the skipped cycle shows
    assert rows["u2 fc03 holding 16..17 (2)"]["count"] == 1 and rows["u2 fc03 holding 16..17 (2)"]["period_ms"] is None
    p.new_capture()  # the next capture's first request: no period across the captures
    p.request(frame(200, 100_000))
    assert {r["type"]: r for r in p.to_dict()["rows"]}["u1 fc03 holding 0..0 (1)"]["max_ms"] == 300


def write_req(index, t_ms, value, pair=None, unit=1):
    raw = bytes([unit, 6, 0, 1]) + value.to_bytes(2, "big") + b"\x00\x00"
    return frame(index, t_ms, unit=unit, fc=6, raw=raw, pair=pair, summary=f"write Setpoint={value}",
                 points=[{"name": "Setpoint", "address": 1, "raw": value, "value": value}])


def test_writes_repeated_are_one_event_with_their_outcomes():
    tl = Timeline()
    assert tl.frame(write_req(0, 0, 500, pair=1))
    tl.frame(frame(1, 10, fc=6, role="response", pair=0))
    assert tl.frame(write_req(2, 100, 500, pair=3))  # the same bytes again: the same event
    tl.frame(frame(3, 110, fc=0x86, role="response", pair=2, exception={"code": 4, "name": "SLAVE DEVICE FAILURE"}))
    assert tl.frame(write_req(4, 200, 500))  # no answer
    assert tl.frame(write_req(5, 300, 600, pair=6))  # another value: a new event
    assert not tl.frame(frame(7, 400))  # a read is no write
    ev = tl.events()
    assert [(e["kind"], e["n"], e["text"]) for e in ev] == [("write", 3, "write Setpoint=500"),
                                                          ("write", 1, "write Setpoint=600")]
    assert ev[0]["outcomes"] == {"confirmed": 1, "exception 04H SLAVE DEVICE FAILURE": 1, "no answer": 1}
    assert ev[0]["t"] == 0 and ev[0]["t_end"] == 200 * MS
    assert tl.counts["write"] == 2


def test_a_fault_is_one_episode_until_the_same_poll_answers_without_it():
    tl = Timeline()
    oh = Annotation("model.fault", "error", "fault: OH", 3, 5)

    def poll(i, t, faulted):
        tl.frame(frame(2 * i, t, pair=2 * i + 1))
        tl.frame(frame(2 * i + 1, t + 5, role="response", pair=2 * i, annotations=[oh] if faulted else []))

    for i, faulted in enumerate([False, True, True, True, False, False, True]):
        poll(i, 100 * i, faulted)
    ev = tl.events()
    assert [(e["kind"], e["n"], e["t"] // MS, e["t_end"] // MS) for e in ev] == [
        ("fault", 3, 105, 305), ("fault", 1, 605, 605)]


def test_head_and_tail_of_many_events():
    tl = Timeline(head=3, tail=2)
    for i in range(10):
        tl.frame(write_req(i, i * 10, i))
    assert [e["text"] for e in tl.events()] == ["write Setpoint=0", "write Setpoint=1", "write Setpoint=2",
                                               "write Setpoint=8", "write Setpoint=9"]
    assert tl.dropped == 5 and tl.counts["write"] == 10


def test_collector_latency_turnaround_and_counts():
    info = CaptureInfo(source="synthetic", baud=9600, parity="N", stopbits=1, time_source="byte", t0_ns=5 * MS)
    c = Collector()
    c.begin("a.mcap", session_of(info))
    char_ms = 10 / 9600 * 1000  # 8N1: 10 bits a character
    lat = [1.0 * char_ms, 3.0 * char_ms, 5.0 * char_ms, 50 * char_ms]
    for i, ms in enumerate(lat):
        c.frame(frame(2 * i, 100 * i + 5, pair=2 * i + 1))
        c.frame(frame(2 * i + 1, 100 * i + 20, role="response", pair=2 * i, latency_ms=ms))
    c.frame(frame(8, 500, crc_ok=False, annotations=[Annotation("modbus.crc.mismatch", "error", "", 0, 8)]))
    c.frame(frame(9, 600, annotations=[Annotation("pair.timeout", "warning", "", 0, 8),
                                       Annotation("pair.retry", "warning", "", 0, 8)]))
    c.end(session_of(info))
    d = c.to_data()
    (u,) = d["units"]
    # the CRC-bad request is a request too, and a CRC error (unitfigures: every view counts so)
    assert (u["requests"], u["responses"], u["crc_errors"], u["timeouts"], u["retries"]) == (6, 4, 1, 1, 1)
    assert u["lat_n"] == 4 and u["lat_min"] == pytest.approx(lat[0], abs=1e-3)
    assert (u["below15"], u["below35"]) == (1, 2)  # 1 char is under t1.5, 1 and 3 under t3.5
    t = d["turnaround"]
    assert sum(t["bins"]["1"]) == 4 and t["bins"]["1"][-1] == 1  # 50 characters: the last bin (40 and more)
    assert t["bins"]["1"][4] == 1 and t["bins"]["1"][20] == 1  # 1 and 5 characters, in bins of 0.25
    assert t["limits"] == [[1.5, 3.5]]
    assert t["time_sources"] == {"byte": 4} and t["capture_time_sources"] == ["byte"]
    b = d["buckets"]
    assert sum(b["frames"]) == 10 and sum(b["crc"]) == 1 and sum(b["timeouts"]) == 1 and sum(b["retries"]) == 1
    assert (sum(b["fast35"]), sum(b["fast15"])) == (2, 1)
    busy = 10 * 8 * 10 * 1e9 / 9600  # ten 8-byte frames of 10-bit characters, in ns
    assert sum(b["busy_ns"]) == pytest.approx(busy, rel=1e-3)
    assert d["axis"]["clock"] is False and d["captures"][0]["start_s"] == 0
    assert d["axis"]["end_s"] == pytest.approx(0.6, abs=0.01)  # t0 (5 ms) is the axis' zero


def test_turnaround_limits_are_fixed_times_above_19200_baud(tmp_path, capsys):
    csv = tmp_path / "fast.mcap"  # slaves answering in 2.5-3.5 characters at 115200, timed per byte
    assert main(["simulate", "--scenario", "fast", "--adapter", "wire", "--duration", "1", "--out", str(csv)]) == 0
    out = tmp_path / "r.html"
    assert cli(capsys, "report", csv, "--out", out)[0] == 0
    d = page_data(out)
    t = d["turnaround"]
    (t15, t35), = t["limits"]
    char_s = 10 / 115200
    assert (t15, t35) == (pytest.approx(750e-6 / char_s, abs=1e-3), pytest.approx(1.75e-3 / char_s, abs=1e-3))
    responses = sum(u["lat_n"] for u in d["units"])
    assert t["capture_time_sources"] == ["byte"] and t["time_sources"] == {"byte": responses}
    assert t["below35"] == t["below15"] == responses > 100  # 2.5-3.5 characters: under 750 us at 115200
    assert t["t35"] > 100  # the framer flags the same frames (modbus.timing.t35)


def test_captures_follow_each_other_or_the_clock():
    c = Collector()
    a = CaptureInfo(baud=9600, t0_ns=0, wall_anchor_ns=1_000_000 * 10**9)
    c.begin("a", session_of(a))
    c.frame(frame(0, 1000))
    c.end(session_of(a))
    b = CaptureInfo(baud=9600, t0_ns=7 * 10**9, wall_anchor_ns=1_000_000 * 10**9 + 60 * 10**9)  # a minute later
    c.begin("b", session_of(b))
    c.frame(frame(0, 7000 + 500))
    c.end(session_of(b))
    d = c.to_data()
    assert d["axis"]["clock"] and [x["start_s"] for x in d["captures"]] == [0, 60]
    assert d["axis"]["end_s"] == pytest.approx(60.505)
    early = CaptureInfo(baud=9600, t0_ns=0, wall_anchor_ns=1_000_000 * 10**9 + 30 * 10**9)  # overlaps b
    c.begin("c", session_of(early))
    assert c.captures[-1]["start_s"] == pytest.approx(60.505) and "overlaps" in c.captures[-1]["note"]
    c.begin("d", session_of(CaptureInfo(baud=9600)))  # no wall clock: the axis counts seconds
    assert not c.to_data()["axis"]["clock"]


def test_a_register_holding_nan_is_a_gap_not_a_broken_page():
    from sniffer.report import render

    info = CaptureInfo(baud=9600, t0_ns=0)
    c = Collector()
    c.begin("f.mcap", session_of(info))
    for i, v in enumerate([1.5, float("nan"), 2.5, float("inf")]):
        raw = [i + 1, 0]
        f = frame(i, 100 * i, role="response", pair=None, writes=[["holding", 0, raw]],
                  points=[{"name": "Temperature", "address": 0, "raw": 65536 * (i + 1), "words": raw, "value": v,
                           "unit": "°C"}])
        c.frame(f)
    c.end(session_of(info))
    d = c.to_data()
    (row,) = d["registers"]["rows"]
    assert (row["name"], row["eng_unit"], row["min"], row["max"], row["last"]) == ("Temperature", "°C", 1.5, 2.5, "inf")
    (series,) = d["registers"]["plots"][0]["series"]
    assert series["v"][:4] == [1.5, None, 2.5, None]
    page = render(d, "t")  # strict JSON: no NaN in it
    assert "NaN" not in page.split('id="report-data">')[1].split("</script>")[0]


# ------------------------------------------------------------------ the command on real captures
def test_report_of_a_capture_counts_what_replay_decodes(tmp_path, capsys):
    out = tmp_path / "r.html"
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--out", out)
    assert rc == 0 and lines == [f"sniffer: wrote {out} ({out.stat().st_size:,} bytes: "
                                 f"{page_data(out)['totals']['frames']:,} frames from 1 capture(s))"]
    _, frames = decoded(SIM / "errors.mcap")
    d = page_data(out)
    assert d["totals"]["frames"] == len(frames)
    units = {u["unit"]: u for u in d["units"]}
    for unit in {f.unit for f in frames if f.unit is not None and not f.is_noise}:
        mine = [f for f in frames if f.unit == unit and not f.is_noise]
        assert units[str(unit)]["crc_errors"] == sum(f.crc_ok is False for f in mine)
        assert units[str(unit)]["requests"] == sum(f.role == "request" for f in mine)
        assert units[str(unit)]["exceptions"] == sum(bool(f.exception) for f in mine if f.role == "response")
        assert units[str(unit)]["ghost"] == all(f.crc_ok is False for f in mine)
    assert sum(d["buckets"]["crc"]) == sum(f.crc_ok is False for f in frames)
    assert d["totals"]["codes"]["pair.retry"] == sum(a.code == "pair.retry" for f in frames for a in f.annotations)
    html = out.read_text()
    assert not re.search(r"<(script|link|img)[^>]+(src|href)=", html)  # nothing loaded from anywhere
    assert "uPlot" in html and "report-data" in html and html.rstrip().endswith("</html>")
    assert left_in(tmp_path) == ["r.html"]


def test_registers_names_and_units_from_the_model(tmp_path, capsys):
    out = tmp_path / "r.html"
    assert cli(capsys, "report", SIM / "a510.mcap", "--out", out)[0] == 0
    r = page_data(out)["registers"]
    names = {(x["unit"], x["name"]): x for x in r["rows"]}
    freq = [x for (u, n), x in names.items() if "Output frequency" in n]
    assert freq and all(x["eng_unit"] == "Hz" and x["changes"] > 0 for x in freq)
    assert any(p["eng_unit"] == "Hz" and p["series"] for p in r["plots"])
    for p in r["plots"]:
        for s in p["series"]:
            assert len(s["t"]) == len(s["v"]) <= 1025 and s["t"] == sorted(s["t"])


def test_poll_types_of_a_protocol_that_is_not_modbus(tmp_path, capsys):
    out = tmp_path / "r.html"
    assert cli(capsys, "report", SIM / "pd-series.mcap", "--out", out)[0] == 0
    rows = {r["type"]: r for r in page_data(out)["polls"]["rows"]}
    status = rows["u1 fc04 read status CFG 1 (Out F: output frequency)"]  # PD: function and status selector
    assert status["count"] > 5 and 500 < status["period_ms"] < 2000
    assert not any("coil" in t or "holding" in t for t in rows)  # no Modbus register reading of PD frames


def test_units_of_several_links_are_their_links(tmp_path, capsys):
    from helpers import bursts, fr

    from sniffer.events import Chunk
    from sniffer.line import LineSettings
    from sniffer.capture.session import EventSource, Session
    from sniffer.formats import FileSink

    read, rsp = fr("010300000002"), fr("01030400010002")

    def on(link: str, line: LineSettings, t0: int) -> list[Chunk]:
        return [Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link) for c in bursts([read, rsp] * 5, line, t0=t0)]

    fast, slow = LineSettings(19200, "E", 1), LineSettings(9600, "N", 1)
    info = CaptureInfo(baud=19200, parity="E", links=[
        {"name": "A", "ports": ["/dev/a"], "tap": False, "baud": 19200, "parity": "E"},
        {"name": "B", "ports": ["/dev/b"], "tap": False, "baud": 9600, "parity": "N"}])
    path = tmp_path / "two.mcap"
    events = sorted(on("A", fast, 0) + on("B", slow, 10**6), key=lambda c: c.t_ns)
    Session(CaptureSpec(), EventSource(info, events), [FileSink("mcap", str(path))]).run()
    out = tmp_path / "r.html"
    assert cli(capsys, "report", path, "--out", out)[0] == 0
    d = page_data(out)
    assert [(u["unit"], u["requests"], u["responses"], u["lat_n"]) for u in d["units"]] == [("A:1", 5, 5, 5),
                                                                                           ("B:1", 5, 5, 5)]
    assert {r["type"] for r in d["polls"]["rows"]} == {"A:u1 fc03 holding 0..1 (2)", "B:u1 fc03 holding 0..1 (2)"}
    assert [(x["name"], x["line"]) for x in d["captures"][0]["links"]] == [("A", "19200 8E1"), ("B", "9600 8N1")]
    busy = 5 * (8 + 9) * (11e9 / 19200 + 10e9 / 9600)  # each link's bytes at its own character time
    assert sum(d["buckets"]["busy_ns"]) == pytest.approx(busy, rel=0.01)
    assert "A: 19200 8E1 modbus-rtu<br>B: 9600 8N1 modbus-rtu" in out.read_text()


def test_several_captures_in_order_on_one_axis(tmp_path, capsys):
    out = tmp_path / "r.html"
    caps = [SIM / "errors.mcap", SIM / "default.mcap"]
    assert cli(capsys, "report", *caps, "--out", out, "--progress")[0] == 0  # a bar per capture on stderr
    d = page_data(out)
    a, b = d["captures"]
    assert (a["label"], b["label"]) == tuple(str(p) for p in caps)
    assert b["start_s"] >= a["end_s"] > 0 and d["axis"]["end_s"] == b["end_s"]
    assert d["totals"]["frames"] == a["frames"] + b["frames"] == sum(len(decoded(p)[1]) for p in caps)
    assert all(len(c["sha256"]) == 64 and c["size"] == os.path.getsize(c["path"]) for c in d["captures"])


def test_a_rotated_capture_is_one_capture(tmp_path, capsys):
    folder = tmp_path / "rot"
    assert main(["replay", str(SIM / "errors.mcap"), "--rotate", "2s", "--out", str(folder)]) == 0
    capsys.readouterr()
    whole, rotated = tmp_path / "whole.html", tmp_path / "rotated.html"
    assert cli(capsys, "report", SIM / "errors.mcap", "--out", whole)[0] == 0
    assert cli(capsys, "report", folder, "--out", rotated)[0] == 0
    a, b = page_data(whole), page_data(rotated)
    assert b["totals"] == a["totals"] and b["units"] == a["units"]
    (c,) = b["captures"]
    assert c["files"] == len(list(folder.iterdir())) > 3 and c["size"] > 0


def test_compare_adds_the_semantic_diff(tmp_path, capsys):
    before, after = tmp_path / "before.mcap", tmp_path / "after.mcap"
    base = ["simulate", "--scenario", "default", "--seed", "4", "--duration", "5"]
    assert main([*base, "--out", str(before)]) == 0
    assert main([*base, "--param", "unit2.rated_current_a=11.0", "--out", str(after)]) == 0
    capsys.readouterr()
    out = tmp_path / "r.html"
    assert cli(capsys, "report", after, "--compare", before, "--out", out)[0] == 0
    c = page_data(out)["compare"]
    assert not c["same"] and c["golden"] == str(before)
    changed = c["diff"]["registers"]["changed"]
    assert "u2 8451 holding[8451]" in changed and all(k.startswith("u2 ") for k in changed)
    assert "captures differ" in c["text"] and "Compared with" in out.read_text()
    assert cli(capsys, "report", before, "--compare", before, "--out", out)[0] == 0
    assert page_data(out)["compare"]["same"]


def test_the_page_opens_with_the_verdicts_diagnose_gives(tmp_path, capsys):
    """The report's first section is the findings of `sniffer diagnose` on the same capture: the same kinds,
    units and order, each with its text, evidence and what to do."""
    cap = tmp_path / "late.mcap"
    assert cli(capsys, "simulate", "--duration", "10", "--fault", "driver_enable_late:2", "--out", cap)[0] == 0
    out = tmp_path / "r.html"
    assert cli(capsys, "report", cap, "--out", out)[0] == 0
    assert main(["diagnose", str(cap), "--format", "json"]) == 0
    said = json.loads(capsys.readouterr().out)["findings"]
    d = page_data(out)
    assert [(f["kind"], f["unit"]) for f in d["findings"]] == [(f["kind"], f["unit"]) for f in said]
    assert d["findings"][0]["kind"] == "driver_enable_late" and d["findings"][0]["unit"] == 2
    html = out.read_text()
    sections = re.findall(r'<section id="([a-z]+)">', html)
    assert sections[0] == "verdicts" and sections[1] == "captures"
    verdicts = html[html.index('<section id="verdicts">'):html.index('<section id="captures">')]
    assert "driver_enable_late" in verdicts and "what to do:" in verdicts and "frames to look at: #" in verdicts
