"""Smaller promises of the core: timings, flags, gaps, pairing rules, function codes."""

from __future__ import annotations

import os
import subprocess
import sys

from helpers import ListSink, bursts, fr, run_events

from sniffer.events import Chunk, Gap, Tick
from sniffer.line import LineSettings
from sniffer.capture.busfile import load_bus_file
from sniffer.formats.saleae import open_saleae_csv

L19 = LineSettings(19200, "E", 1)




def codes_of(f):
    return [a.code for a in f.annotations]


def test_t15_t35_from_baud_and_character_size():
    assert LineSettings(9600, "N", 1).bits_per_char == 10
    assert LineSettings(9600, "E", 1).bits_per_char == 11
    assert LineSettings(9600, "N", 2).bits_per_char == 11
    l96 = LineSettings(9600, "E", 1)
    assert l96.t35_ns == 11 * 10**9 // 9600 * 7 // 2  # about 4.01 ms
    assert l96.t15_ns == 11 * 10**9 // 9600 * 3 // 2
    fast = LineSettings(115200, "N", 1)
    assert (fast.t15_ns, fast.t35_ns) == (750_000, 1_750_000)  # fixed above 19200 baud


def test_uart_flags_are_kept_on_the_frame():
    data = bytes.fromhex(fr("0103000a0001"))
    times = tuple(i * L19.char_ns for i in range(len(data)))
    (f,) = run_events([Chunk(0, data, times, ((3, "parity"),))], L19)
    a = [x for x in f.annotations if x.code == "uart.parity_error"]
    assert a and (a[0].start, a[0].end) == (3, 4)


def test_gap_annotates_the_first_frame_after_it():
    req = bytes.fromhex(fr("0103000a0001"))
    t1 = 5_000_000_000
    events = [
        Chunk(0, req, tuple(i * L19.char_ns for i in range(8))),
        Gap(100_000_000, 4_000_000_000, "port lost (EIO), reopened"),
        Chunk(t1, req, tuple(t1 + i * L19.char_ns for i in range(8))),
    ]
    sink = ListSink()
    frames = run_events(events, L19, sinks=[sink])
    assert "source.gap" not in codes_of(frames[0]) and "source.gap" in codes_of(frames[1])
    assert any(isinstance(e, Gap) for e in sink.events)


def test_inter_character_gap_over_t15_is_flagged():
    data = bytes.fromhex(fr("0103000a0001"))
    times = [i * L19.char_ns for i in range(len(data))]
    times[4:] = [t + 2 * L19.char_ns for t in times[4:]]  # 2 characters of silence mid-frame
    (f,) = run_events([Chunk(0, data, tuple(times))], L19)
    assert f.crc_ok and "modbus.timing.t15" in codes_of(f)


def test_write_echo_and_broadcast_and_retry_and_timeout():
    w = fr("010600010055")
    bc = fr("000600010055")
    rd = fr("0203000a0001")
    frames = run_events(
        bursts([w, w, bc, rd, rd, fr("0203020007")], L19, gap_chars=40) + [Tick(10**10)], L19
    )
    assert [f.role for f in frames] == ["request", "response", "request", "request", "request", "response"]
    assert frames[1].pair == 0 and frames[1].summary.startswith("wrote")
    assert "pair.broadcast" in codes_of(frames[2]) and frames[2].pair is None
    assert "pair.no_response" in codes_of(frames[3]) and "pair.retry" in codes_of(frames[4])
    assert frames[5].pair == 4


def test_per_unit_timeout_from_bus_file(tmp_path):
    bus = tmp_path / "bus.toml"
    bus.write_text('[serial]\nbaud = 19200\nparity = "E"\n[units]\n1 = "generic"\n[timeouts_ms]\n1 = 5\n')
    b = load_bus_file(str(bus))
    assert (b.baud, b.parity, b.devices, b.timeouts_ms) == (19200, "E", {1: "generic"}, {1: 5.0})
    req = fr("0103000a0001")
    frames = run_events(bursts([req, req], L19, gap_chars=20), L19, unit_timeouts=b.timeouts_ms)
    assert "pair.timeout" in codes_of(frames[0])  # 20 characters > 5 ms at 19200
    frames = run_events(bursts([req, req], L19, gap_chars=20), L19)
    assert "pair.timeout" not in codes_of(frames[0])  # default 1000 ms


def test_less_common_function_codes_decode():
    cases = [
        (fr("01080000a537"), fr("01080000a537"), "diagnostics"),
        (fr("0111"), fr("011105414243ff00"), "report server id"),
        (fr("0116000400f20025"), fr("0116000400f20025"), "mask write"),
        (fr("011700030006000e00030600ff00ff00ff"), fr("01170c00fe0acd00010003000d00ff"), ""),
        (fr("012b0e0100"), fr("012b0e01010000020003414243010144"), "MEI"),
        (fr("0107"), fr("01076d"), "exception status"),
    ]
    for req, rsp, word in cases:
        a, b = run_events(bursts([req, rsp], L19), L19)
        assert (a.role, b.role, b.pair) == ("request", "response", a.index), (req, rsp)
        assert a.crc_ok and b.crc_ok
        assert not [x for f in (a, b) for x in f.annotations if x.severity == "error"], (a, b)
        assert word in (a.summary + b.summary) or word == ""
    a, b = run_events(bursts([cases[3][0], cases[3][1]], L19), L19)
    assert [p["address"] for p in b.points] == [3, 4, 5, 6, 7, 8]
    assert [p["address"] for p in a.points] == [14, 15, 16]


def test_exception_response_named():
    a, b = run_events(bursts([fr("0103000a0001"), fr("018302")], L19), L19)
    assert b.role == "response" and b.pair == a.index
    assert b.exception == {"code": 2, "name": "ILLEGAL DATA ADDRESS"}


def test_unknown_function_shown_raw():
    (a,) = run_events(bursts([fr("01410102")], L19), L19)
    assert a.crc_ok and "modbus.function.user_defined" in codes_of(a)


def test_saleae_logic2_export_reads_like_the_byte_csv(tmp_path):
    """A Logic 2 async-serial export of the wizmodbus bytes decodes to the same frames."""
    from refdata import SIGROK
    import csv

    rows = list(csv.DictReader(open(SIGROK / "wizmodbus.bytes.csv")))
    out = tmp_path / "logic2.csv"
    with open(out, "w") as fh:
        fh.write("name,type,start_time,duration,data\n")
        for r in rows:
            fh.write(f'"Async Serial {r["channel"]}","data",{r["t_s"]},0.000937,0x{r["byte_hex"].upper()}\n')
    info, events = open_saleae_csv(str(out))
    frames = run_events(events, LineSettings(9600), info=info)
    assert len(frames) == 88 and all(f.crc_ok for f in frames)
    logic1 = tmp_path / "logic1.csv"
    with open(logic1, "w") as fh:
        fh.write("Time [s],Value,Parity Error,Framing Error\n")
        for r in rows:
            fh.write(f"{r['t_s']},0x{r['byte_hex'].upper()},,\n")
    info, events = open_saleae_csv(str(logic1))
    assert len(run_events(events, LineSettings(9600), info=info)) == 88


def test_full_disk_stops_live_capture_cleanly(tmp_path):
    """`sniffer demo` with a real 100 kB file-size limit: one error line, exit 1, file readable.

    (40 kB before the Foxglove channels: the first second's flush, a channel per register and the
    registers' first values, is 46 kB now, and a flush is kept whole or not at all.)"""
    import resource

    out = tmp_path / "full.mcap"
    code = (
        "import resource,sys; resource.setrlimit(resource.RLIMIT_FSIZE,(100000,100000));"
        "import signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN);"
        "from sniffer.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    r = subprocess.run([sys.executable, "-c", code, "demo", "--headless", "--duration", "30", "--out", str(out)],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    errors = [l for l in r.stderr.splitlines() if "error" in l]
    assert len(errors) == 1 and "Traceback" not in r.stderr
    # what carries the final name is complete; a capture whose end could not be written stays NAME.part,
    # and the error line names it (which of the two depends on where the limit struck)
    kept = out if out.exists() else tmp_path / "full.mcap.part"
    assert kept.exists() and not (out.exists() and kept != out)
    if kept != out:
        assert kept.name in errors[0], errors
    else:
        from mcap.reader import make_reader

        with open(out, "rb") as fh:
            assert make_reader(fh).get_summary() is not None  # a standard reader reads it whole
    assert os.path.getsize(kept) <= 100000
    r2 = subprocess.run([sys.executable, "-m", "sniffer", "replay", str(kept), "--format", "jsonl"],
                        capture_output=True, text=True, timeout=60)
    assert r2.returncode == 0, r2.stderr
    assert len(r2.stdout.splitlines()) > 10
    del resource


def test_register_shadow_keeps_only_what_crc_good_frames_said():
    """A corrupted read response is decoded for the eye, but its values do not enter the shadow."""
    from decoders.registry import default_registry
    from sniffer.capture.pipeline import Pipeline
    from sniffer.events import CaptureInfo

    good = fr("0103020064")  # holding[10] = 100
    bad = fr("01030201c8")[:-4] + "0000"  # 456, CRC broken
    write_bad = fr("0106000a0309")[:-4] + "ffff"  # an echo of a write with a broken CRC
    frames_hex = [fr("0103000a0001"), good, fr("0103000a0001"), bad, fr("0106000a0309"), write_bad]
    reg = default_registry()
    p = Pipeline(CaptureInfo(baud=L19.baud, parity=L19.parity, stopbits=L19.stopbits), L19, reg)
    out = []
    for ev in bursts(frames_hex, L19):
        out += p.feed(ev)
    out += p.finish()
    rsp_bad = out[3]
    assert rsp_bad.crc_ok is False and rsp_bad.points[0]["value"] == 456  # still shown
    assert reg.states[1].holding[10] == 100  # ... but the shadow kept the CRC-good value
