"""`sniffer check` (with timing tolerances) and `sniffer diff` (the semantic diff of two captures)."""

from __future__ import annotations

import orjson
import pytest

from sniffer.analysis.check import EXIT_DIFFERENT, EXIT_ERROR, EXIT_SAME, Tolerances, compare_text
from sniffer.commands.check import check
from sniffer.commands.diff import diff
from sniffer.capture.session import CaptureSpec
from pathlib import Path

CAPTURES = Path(__file__).resolve().parent.parent / "captures"

A510 = CAPTURES / "sim" / "a510.mcap"
DEFAULT = CAPTURES / "sim" / "default.mcap"
ERRORS = CAPTURES / "sim" / "errors.mcap"
WIZ = CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"


@pytest.fixture(scope="module")
def a510_golden(tmp_path_factory):
    g = tmp_path_factory.mktemp("golden") / "a510.txt"
    rc, text = check(A510, g, update=True)
    assert rc == EXIT_SAME and "wrote" in text
    return g


def _shift(text: str, line_no: int, dt_s: float = 0.0, dlat: float = 0.0) -> str:
    lines = text.splitlines()
    head, _, content = lines[line_no].partition(" | ")
    t, lat = head.split(" ")
    lat = lat if lat == "-" else f"{float(lat) + dlat:.3f}"
    lines[line_no] = f"{float(t) + dt_s:.6f} {lat} | {content}"
    return "\n".join(lines) + "\n"


def test_same_capture_passes(a510_golden):
    assert check(A510, a510_golden) == (EXIT_SAME, "ok: 502 frames, 0 findings match\n")


def test_golden_is_one_line_per_frame_with_timing_columns(a510_golden):
    lines = a510_golden.read_text().splitlines()
    assert lines[0].startswith("# sniffer golden v2")
    assert len(lines) == 1 + 502
    assert all(" | " in x for x in lines[1:])
    assert "response u1 a510 fc10 crc=ok pair=-1" in lines[2]


def test_timing_within_tolerance_passes_beyond_fails(tmp_path, a510_golden):
    g = tmp_path / "g.txt"
    g.write_text(_shift(a510_golden.read_text(), 5, dt_s=0.0004))
    assert check(A510, g)[0] == EXIT_SAME
    g.write_text(_shift(a510_golden.read_text(), 5, dt_s=0.005))
    rc, text = check(A510, g)
    assert rc == EXIT_DIFFERENT and "1 of 502 frames differ (1 changed" in text and " time " in text
    rc, text = check(A510, g, diff=True)
    assert text.count("\n-") >= 1
    # only the shifted frame is in the diff
    assert [x for x in text.splitlines() if x.startswith("-") and not x.startswith("---")][0].startswith("-0.")
    assert check(A510, g, tolerances=Tolerances(time_ms=10))[0] == EXIT_SAME


def test_latency_tolerance(tmp_path, a510_golden):
    g = tmp_path / "g.txt"
    g.write_text(_shift(a510_golden.read_text(), 2, dlat=3.0))  # line 2 is a response
    assert check(A510, g)[0] == EXIT_DIFFERENT
    assert check(A510, g, tolerances=Tolerances(latency_ms=5))[0] == EXIT_SAME


def test_content_change_is_a_difference_whatever_the_tolerance(tmp_path, a510_golden):
    g = tmp_path / "g.txt"
    g.write_text(a510_golden.read_text().replace("pair=-1 wrote 2501H", "pair=-1 wrote 2501h", 1))
    rc, text = check(A510, g, tolerances=Tolerances(time_ms=1e9, latency_ms=1e9), diff=True)
    assert rc == EXIT_DIFFERENT
    assert "-0.026568 11.757 | response u1 a510 fc10 crc=ok pair=-1 wrote 2501h" in text
    assert "+0.026568 11.757 | response u1 a510 fc10 crc=ok pair=-1 wrote 2501H" in text


def test_update_rewrites_and_shows_what_changed(tmp_path, a510_golden):
    g = tmp_path / "g.txt"
    g.write_text(a510_golden.read_text().replace("wrote 2501H", "wrote X", 1))
    rc, text = check(A510, g, update=True)
    assert rc == EXIT_SAME and "wrote X" in text
    assert g.read_text() == a510_golden.read_text()


def test_errors_exit_2(tmp_path):
    rc, text = check(A510, tmp_path / "missing.txt")
    assert rc == EXIT_ERROR and "--update-golden" in text
    rc, text = check(tmp_path / "nope.mcap", tmp_path / "g.txt")
    assert rc == EXIT_ERROR and "no such file" in text
    rc, text = check(WIZ, tmp_path / "g.txt", update=True)  # a CSV does not say its baud rate
    assert rc == EXIT_ERROR and "baud" in text
    rc, _ = check(WIZ, tmp_path / "g.txt", update=True, spec=CaptureSpec.of(baud=9600))
    assert rc == EXIT_SAME


def test_compare_text_inserted_frame():
    old = "h\n0.1 - | a\n0.2 - | b\n"
    new = "h\n0.1 - | a\n0.15 - | x\n0.2004 - | b\n"
    d = compare_text(old, new)
    assert "+0.15 - | x" in d and "0.2004" not in d


def test_diff_same_capture_is_same():
    r = diff(A510, A510)
    assert r.same
    assert "no semantic difference" in r.to_text()


def test_diff_finds_units_requests_errors_and_latency():
    r = diff(DEFAULT, ERRORS)
    d = r.to_dict()
    assert not r.same
    assert "9" in d["units"]["added"] and "5" in d["units"]["removed"]
    assert any(k.startswith("u9 fc03") for k in d["requests"]["added"])
    assert "pair.no_response" in d["codes"]["new"]
    assert any(k.startswith("exception.") for k in d["codes"]["new"])
    assert d["latency_ms"]["a"]["median"] is not None and d["latency_ms"]["a"]["p95"] is not None
    orjson.dumps(d)  # JSON output
    text = r.to_text()
    assert "+ unit 9" in text and "+ pair.no_response" in text and "latency: median" in text


def test_diff_names_registers_from_the_model():
    d = diff(DEFAULT, A510).to_dict()
    names = {v["name"] for v in d["registers"]["added"].values()}
    assert "Frequency command" in names
    assert d["units"]["models"]["1"] == "a510"


def _pcap(path, value: int, period_s: float = 0.1, n: int = 5, exception: bool = False):
    from sniffer.framing.crc import crc_bytes
    from sniffer.formats.pcap.format import global_header, packet

    req = bytes.fromhex("010300100001")
    rsp = bytes.fromhex("018302") if exception else bytes([1, 3, 2]) + value.to_bytes(2, "big")
    with open(path, "wb") as fh:
        fh.write(global_header())
        for i in range(n):
            t = 1_700_000_000_000_000_000 + int(i * period_s * 1e9)
            fh.write(packet(t, req + crc_bytes(req)))
            fh.write(packet(t + 20_000_000, rsp + crc_bytes(rsp)))
    return path


def test_diff_register_value_change_period_and_exception(tmp_path):
    a = _pcap(tmp_path / "a.pcap", 42)
    b = _pcap(tmp_path / "b.pcap", 43, period_s=0.5)
    opts = CaptureSpec.of(baud=9600)
    d = diff(a, b, opts).to_dict()
    (key, change), = d["registers"]["changed"].items()
    assert key.startswith("u1 16 ")
    assert change["a"]["values"] == [42] and change["b"]["values"] == [43]
    (req, periods), = d["requests"]["period_changed"].items()
    assert req == "u1 fc03 holding 16..16 (1)" and periods == [100.0, 500.0]
    assert "42" in diff(a, b, opts).to_text() and "43" in diff(a, b, opts).to_text()
    c = diff(a, _pcap(tmp_path / "c.pcap", 0, exception=True), opts).to_dict()
    assert "exception.02" in c["codes"]["new"]


def test_an_inserted_frame_is_one_diff_line(tmp_path, a510_golden):
    lines = a510_golden.read_text().splitlines()
    del lines[10]  # the golden lacks one frame that the capture has
    g = tmp_path / "g.txt"
    g.write_text("\n".join(lines) + "\n")
    rc, text = check(A510, g, diff=True)
    assert rc == EXIT_DIFFERENT
    assert "1 of 502 frames differ (0 changed, 1 added, 0 missing)" in text
    assert "first: frame 9 at " in text and ": added" in text
    unified = text[text.index("\n--- ") + 1:]
    changed = [x for x in unified.splitlines()[2:] if x[:1] in "+-"]
    assert len(changed) == 1 and changed[0].startswith("+")


def test_summary_ignores_what_a_crc_bad_frame_claims():
    """A frame damaged on the line says nothing reliable about units, requests or exceptions: only its
    error codes count (diffs of two captures of one bus must not list phantom units)."""
    from sniffer.codes import CRC_MISMATCH, note
    from sniffer.frame import Frame
    from sniffer.analysis.diff import summarize

    good = Frame(0, 0, 1, bytes.fromhex("0103000a0001a408"), "modbus-rtu", 1, 3, crc_ok=True)
    good.role = "request"
    bad = Frame(1, 10, 11, bytes.fromhex("4d83021234"), "modbus-rtu", 0x4D, 0x83, crc_ok=False)
    bad.role, bad.exception = "response", {"code": 2, "name": "ILLEGAL DATA ADDRESS"}
    bad.annotations.append(note(CRC_MISMATCH, "bad", 3, 5))
    s = summarize([good, bad])
    assert list(s["units"]) == ["1"] and len(s["requests"]) == 1
    assert s["codes"] == {"modbus.crc.mismatch": 1}  # counted as an error, not as unit 77's exception


def test_quantiles_are_exact_then_within_a_tenth_of_a_percent():
    """diff keeps latencies and poll gaps in bounded memory: exact up to EXACT samples, a 0.1 % histogram beyond."""
    import random
    import statistics

    from sniffer.analysis.diff import Quantiles

    rng = random.Random(5)
    xs = [rng.lognormvariate(1.5, 0.6) for _ in range(Quantiles.EXACT * 3)]
    small, big = Quantiles(), Quantiles()
    for x in xs[:1000]:
        small.add(x)
    for x in xs:
        big.add(x)
    assert small.median() == statistics.median(xs[:1000])
    assert small.pct(0.95) == round(sorted(xs[:1000])[round(0.95 * 999)], 3)
    assert big._xs is None  # switched to the histogram
    exact = sorted(xs)
    assert abs(big.median() - statistics.median(xs)) <= 0.001 * statistics.median(xs)
    for q in (0.05, 0.5, 0.95, 0.999):
        want = exact[round(q * (len(xs) - 1))]
        assert abs(big.pct(q) - want) <= 0.001 * want + 0.0005, q


def test_a_value_past_the_summarys_sixth_point_is_checked(tmp_path, a510_golden):
    """Found by an outside review: the golden held the summary only ("... (+10)"), so a value changed in
    the 7th register of a read passed.  v2 lines carry the rest of the points."""
    text = a510_golden.read_text()
    lines = text.splitlines()
    k = next(i for i, x in enumerate(lines) if " | rest: " in x)
    rest = lines[k].split(" | rest: ", 1)[1]
    name, _, after = rest.partition("=")
    value = after.split(" ", 1)[0]
    changed = lines[k].replace(f" | rest: {name}={value}", f" | rest: {name}={value}9", 1)
    assert changed != lines[k]
    g = tmp_path / "g.txt"
    g.write_text("\n".join(lines[:k] + [changed] + lines[k + 1:]) + "\n")
    rc, summary = check(A510, g)
    assert rc == EXIT_DIFFERENT and f"first: frame {k - 1} " in summary and f"{name} {value}9 " in summary


def test_a_v1_golden_is_still_checked_as_v1(tmp_path, a510_golden):
    lines = a510_golden.read_text().splitlines()
    v1 = ["# sniffer golden v1: t_s latency_ms | role unit model fc crc pair(offset) summary [codes]"]
    for x in lines[1:]:
        head, sep, rest = x.partition(" | rest: ")
        codes = rest[rest.rfind(" ["):] if sep and rest.endswith("]") and " [" in rest else ""
        v1.append(head + codes if sep else x)
    g = tmp_path / "v1.txt"
    g.write_text("\n".join(v1) + "\n")
    assert check(A510, g) == (EXIT_SAME, "ok: 502 frames, 0 findings match\n")
