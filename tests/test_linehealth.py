"""The line-settings warning: most frames bad in the first seconds -> one warning naming `sniffer detect`.

The rule (sniffer/analysis/linehealth.py) on synthetic frames (time, size, badness); then real
simulated captures: one received at the wrong settings warns within seconds, the `errors` scenario
(a healthy line with about one bad frame in ten) does not; the CLI says it in one stderr line."""

from __future__ import annotations

import random

import pytest
from helpers import bursts, fr, run_sniffer

from sniffer import codes
from sniffer.analysis.linehealth import (
    BROKEN_SHARE, CRC, MIN_FRAMES, NOISE, RECOVERED_SHARE, UART, WINDOW_S, LineHealth, LineWarning, LineWatch,
    badness, is_line_warning,
)
from sniffer.capture.session import CaptureSpec, Session
from sniffer.detect.hint import first_settings, what_to_do
from sniffer.events import CaptureInfo, FLAG_PARITY, Chunk
from sniffer.frame import Frame
from sniffer.line import LineSettings
from sniffer.simulator import get_scenario
from sniffer.simulator.sources import SimulatedSource

S = 1_000_000_000


def feed(h: LineHealth, frames):
    """frames: (t_s, size, badness) -> the changes, with the time each came at."""
    out = []
    for t, size, bad in frames:
        c = h.add(int(t * S), size, bad)
        if c is not None:
            out.append((t, c))
    return out


def poll(t0: float, seconds: float, per_s: float = 20, bad_every: int = 0, kind=CRC, size: int = 8):
    """A polled line: `per_s` frames a second; every `bad_every`-th bad (0: none; 1: all)."""
    n = int(seconds * per_s)
    return [(t0 + i / per_s, size, kind if bad_every and i % bad_every == 0 else None) for i in range(n)]


# ---------------------------------------------------------------- the rule


def test_a_line_of_bad_frames_breaks_once_within_seconds():
    h = LineHealth()
    changes = feed(h, poll(0, 30, bad_every=1, kind=NOISE))
    assert [c.broken for _, c in changes] == [True]  # once, however long it stays bad
    t, c = changes[0]
    assert t <= 1.5 and c.bad == c.frames >= MIN_FRAMES and c.kinds == (0, 0, c.bad)
    assert "CRC errors, UART errors or noise (noise" in c.describe()


def test_a_burst_at_the_start_is_not_yet_the_first_seconds():
    """Eight bad frames in 0.1 s (a unit booting as the capture starts), then a good line: nothing said."""
    h = LineHealth()
    assert feed(h, [(i / 80, 8, NOISE) for i in range(8)] + poll(0.2, 20)) == []


def test_a_healthy_line_with_a_few_errors_never_warns():
    rnd = random.Random(4)
    h = LineHealth()
    frames = [(i / 20, rnd.randint(8, 40), rnd.choice((CRC, UART, NOISE)) if rnd.random() < 0.2 else None)
              for i in range(20 * 600)]
    assert feed(h, frames) == []


def test_a_capture_that_starts_in_the_middle_of_a_frame_does_not_warn():
    h = LineHealth()
    assert feed(h, [(0.0, 5, NOISE)] + poll(0.01, 10)) == []


def test_a_quiet_line_decides_nothing():
    """A frame every two seconds is never enough to judge, however bad: a quiet line is not a wrong one."""
    h = LineHealth()
    assert feed(h, [(2.0 * i, 40, NOISE) for i in range(100)]) == []
    assert not h.broken


def test_one_long_noise_burst_among_small_good_frames_is_not_most():
    """Most of the bytes, not most of the frames: both must be bad."""
    h = LineHealth()
    frames = poll(0, 2, per_s=5) + [(2.05, 250, NOISE)] + poll(2.1, 3, per_s=5)
    assert feed(h, frames) == []
    assert h.bad_bytes > BROKEN_SHARE * h.nbytes  # the bytes alone would have said it


def test_recovery_and_a_new_break_say_it_again_once():
    h = LineHealth()
    frames = poll(0, 10, bad_every=1) + poll(10, 10) + poll(20, 10, bad_every=1, kind=UART) + poll(30, 10)
    changes = feed(h, frames)
    assert [c.broken for _, c in changes] == [True, False, True, False]
    (t1, _), (t2, _), (t3, _), (t4, _) = changes
    assert t1 < 2 and 10 < t2 < 10 + WINDOW_S + 0.5 and 30 < t4 < 30 + WINDOW_S + 0.5
    assert 20 < t3 < 20 + WINDOW_S / 2 + 0.5  # once the window's newer half is bad
    assert h.warnings == 2


def test_between_the_two_shares_nothing_changes():
    """Broken, then a third bad: neither recovered (more than RECOVERED_SHARE) nor said again."""
    h = LineHealth()
    assert RECOVERED_SHARE < 1 / 3 < BROKEN_SHARE
    changes = feed(h, poll(0, 5, bad_every=1) + poll(5, 60, bad_every=3))
    assert [c.broken for _, c in changes] == [True] and h.broken


def test_a_fast_line_is_judged_on_its_last_frames():
    """1000 frames a second: the window is its last MAX_FRAMES frames, judged well within a second."""
    h = LineHealth()
    changes = feed(h, poll(0, 2, per_s=1000, bad_every=1))
    assert len(changes) == 1 and changes[0][0] < 0.5


# ---------------------------------------------------------------- frames


def _frame(t_s: float, raw: bytes, link: str = "", *, protocol="modbus-rtu", crc_ok=True, uart=False) -> Frame:
    f = Frame(0, int(t_s * S), int(t_s * S) + 1000, raw, protocol, crc_ok=crc_ok)
    f.link = link
    if uart:
        f.annotations.append(codes.note(codes.UART_PARITY, "x", 0, 1))
    return f


def test_badness_of_real_frames():
    """Noise, a CRC mismatch, a byte with a parity error: the framer's own frames."""
    line = LineSettings(19200, "E", 1)
    good, bad_crc = fr("010300000002"), fr("010300000002")[:-2] + "00"
    chunks = bursts([good, bad_crc, "ffee"], line)
    t = chunks[-1].byte_t_ns[-1] + 10 * line.char_ns
    data = bytes.fromhex(good)
    chunks.append(Chunk(t, data, tuple(t + i * line.char_ns for i in range(len(data))), ((2, FLAG_PARITY),)))
    from helpers import run_events

    frames = run_events(chunks, line)
    assert [badness(f) for f in frames] == [None, CRC, NOISE, UART]


def test_each_link_is_judged_on_its_own():
    w = LineWatch()
    said = []
    for i in range(200):
        for link, ok in (("drives", True), ("pumps", False)):
            c = w.frame(_frame(i / 20, b"\x01\x03\x00\x00\x00\x02\xc4\x0b", link, crc_ok=ok))
            if c is not None:
                said.append(c)
    assert [(c.link, c.broken) for c in said] == [("pumps", True)] and w.broken() == ["pumps"]


# ---------------------------------------------------------------- the hint


def test_the_hint_names_detect_on_the_port_and_what_it_tries_first():
    info = CaptureInfo(source="serial:/dev/ttyUSB0", port="/dev/ttyUSB0", baud=9600, parity="N", stopbits=1)
    text = what_to_do(info)
    assert "sniffer detect /dev/ttyUSB0" in text and "sending nothing" in text
    assert all(s in text for s in first_settings()) and first_settings()[0] == "9600 8N1"
    links = CaptureInfo(source="serial:a,b", links=[{"name": "a", "ports": ["/dev/ttyUSB0"]},
                                                    {"name": "b", "ports": ["/dev/ttyUSB7"]}])
    assert "sniffer detect /dev/ttyUSB7 " in what_to_do(links, "b")
    replayed = what_to_do(info, file="line3.mcap")  # a file cannot be listened to: its port can
    assert "not a file" in replayed and "sniffer detect /dev/ttyUSB0" in replayed and "--protocol" in replayed
    assert "9600 8N1" in replayed


# ---------------------------------------------------------------- simulated captures


def _session_warnings(scenario: str, receiver: LineSettings | None, seconds: float = 20, adapter: str = "usb"):
    """Warnings a capture's LineWarning says, with the frame time (s from the capture's start) each came at."""
    sc = get_scenario(scenario)
    said = []
    sink = LineWarning(lambda info, link: what_to_do(info, link, file="x.mcap"), said.append)
    session = Session(CaptureSpec(), SimulatedSource(sc, sc.line, seconds, 3, adapter, receiver=receiver), [sink])
    whens = []
    for f in session:  # each frame as the sinks got it
        if len(said) > len(whens):
            whens.append((f.t_ns - session.info.t0_ns) / S)
    return said, whens


@pytest.mark.parametrize("receiver, adapter", [
    (LineSettings(9600, "E", 1), "usb"),  # the default line runs 19200 8E1: a wrong baud rate
    (LineSettings(38400, "N", 1), "usb"),
    (LineSettings(19200, "O", 1), "wire"),  # a wrong parity, flagged byte by byte (a logic analyzer's view)
])
def test_a_capture_at_wrong_settings_warns_once_within_seconds(receiver, adapter):
    said, whens = _session_warnings("default", receiver, adapter=adapter)
    assert len(said) == 1 and whens[0] < 3.0, (said, whens)
    assert said[0].startswith("warning: ") and is_line_warning(said[0])
    assert f"({receiver.baud} 8{receiver.parity}1)" in said[0]


@pytest.mark.parametrize("scenario", ["errors", "default", "fast", "a510-ascii", "pd-series", "tds-v8"])
def test_right_settings_never_warn(scenario):
    said, _ = _session_warnings(scenario, None)
    assert said == []


def test_replay_of_a_capture_at_the_wrong_baud_says_it_in_one_line(tmp_path):
    cap = tmp_path / "wrong.mcap"
    r = run_sniffer("simulate", "--scenario", "default", "--receiver-baud", "9600", "--duration", "10",
                    "--out", str(cap))
    assert r.returncode == 0, r.stderr
    r = run_sniffer("replay", str(cap), "--quiet")
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if is_line_warning(ln)]
    assert len(lines) == 1 and lines[0].startswith("sniffer: warning: ")
    assert "(9600 8E1)" in lines[0] and "sniffer detect" in lines[0] and "not a file" in lines[0]


def test_demo_of_the_errors_scenario_does_not_warn():
    r = run_sniffer("demo", "--scenario", "errors", "--duration", "6", "--headless", "--quiet", "--no-out")
    assert r.returncode == 0, r.stderr
    assert "probably wrong" not in r.stderr and "simulator sent" in r.stderr


def test_live_at_the_wrong_baud_names_detect_on_the_port(tmp_path):
    """A real pty line at 19200 8E1 read at 9600: the warning names the port and what detect tries first."""
    from helpers import SimulatedLine

    with SimulatedLine(tmp_path, "default") as line:
        r = run_sniffer("live", line.path, "--baud", "9600", "--headless", "--quiet", "--no-out", "--duration", "5")
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if is_line_warning(ln)]
    assert len(lines) == 1, r.stderr
    assert f"run sniffer detect {line.path} " in lines[0] and "(9600 8N1)" in lines[0]
    assert all(s in lines[0] for s in first_settings())


def test_a_logic_capture_is_measured_by_detect(tmp_path):
    """A sigrok .sr file (or a live analyzer) has the bits: detect measures them, a replay's flags are not the way."""
    import zipfile

    sr = tmp_path / "x.sr"
    with zipfile.ZipFile(sr, "w") as z:
        z.writestr("metadata", "[device 1]\nsamplerate=1 MHz\ntotal probes=1\nprobe1=rx\n")
        z.writestr("version", "2")
    info = CaptureInfo(source=f"sigrok:{sr}", baud=9600)
    assert what_to_do(info, file=str(sr)).startswith(f"run sniffer detect {sr} (it measures the bits")
    live = CaptureInfo(source="sigrok:fx2lafw", port="sigrok:fx2lafw", baud=9600)
    assert what_to_do(live).startswith("run sniffer detect sigrok:fx2lafw (it measures the bits")
