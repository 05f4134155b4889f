"""A simulated line received at other settings: RxBursts for captures, LiveLine / SimulatedPort for detect,
PtyLine on a real pseudo-terminal (the sniffer's end set with the real port code, nothing written back)."""

from __future__ import annotations

import os
import select
import threading
import time

from sniffer.framing.crc import crc_ok
from sniffer.events import FLAG_FRAMING, FLAG_PARITY
from sniffer.line import LineSettings
from sniffer.sources.parmrk import InputFlags, MarkReader
from sniffer.sources.pty_settings import PortSettings
from sniffer.simulator import get_scenario, simulate
from sniffer.simulator.received import LiveLine, received
from sniffer.simulator.simport import SimulatedPort
from sniffer.simulator.uartpty import PtyLine
from sniffer.sources.serial_port import configure, open_read_only

SC = get_scenario("default")  # 19200 8E1
MARKED = InputFlags(parmrk=True, inpck=True)


def _sent(seconds=1.0):
    return list(simulate(SC, SC.line, seconds, 3))


def test_received_at_the_line_settings_is_what_was_sent():
    frames = _sent()
    bursts = list(received(frames, SC.line, SC.line))
    assert b"".join(b.raw for b in bursts) == b"".join(f.raw for f in frames)
    assert not any(b.flags for b in bursts)


def test_received_at_other_settings_carries_the_uart_flags():
    frames = _sent()
    odd = list(received(frames, SC.line, LineSettings(19200, "O", 1)))
    assert b"".join(b.raw for b in odd) == b"".join(f.raw for f in frames)  # data bits right...
    assert all(len(b.flags) == len(b.raw) and {f for _, f in b.flags} == {FLAG_PARITY} for b in odd)  # ...all marked
    none = list(received(frames, SC.line, LineSettings(19200, "N", 1)))
    flagged = {i for b in none for i, _ in b.flags}
    assert flagged and {f for b in none for _, f in b.flags} == {FLAG_FRAMING}


def test_live_line_retuned_mid_frame_receives_at_the_new_setting_from_then_on():
    frames = _sent(0.5)
    line = LiveLine(iter(frames), SC.line)
    right = PortSettings(SC.line, MARKED)
    first = line.step(right)
    assert b"".join(d for _, d in first) == frames[0].raw
    t = line.next_t_ns
    second = line.step(right)
    mid = (frames[1].t_ns + frames[1].t_end_ns) // 2
    retuned = line.retune(PortSettings(LineSettings(19200, "O", 1), MARKED), mid)
    assert retuned and all(due > mid for due, _ in retuned) and t == frames[1].t_ns
    assert b"\xff\x00" in b"".join(d for _, d in retuned)  # parity errors, marked
    assert len(b"".join(d for _, d in second)) >= len(frames[1].raw)


def test_simulated_port_is_deterministic_and_flushes_on_configure():
    def run():
        port = SimulatedPort(SC, SC.line, start_s=0.05)
        port.configure(SC.line)
        out = []
        while port.now() < 0.5e9:
            data = port.read(0.005)
            if data:
                out.append((port.now(), data))
        return out
    a, b = run(), run()
    assert a == b and sum(len(d) for _, d in a) > 300
    data, marks = MarkReader().feed(b"".join(d for _, d in a))
    assert not marks and data in b"".join(f.raw for f in simulate(SC, SC.line, 1.0, 1))


def _read_for(fd, seconds):
    out = b""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if select.select([fd], [], [], 0.02)[0]:
            out += os.read(fd, 4096)
    return out


def test_pty_line_delivers_what_a_uart_at_the_sniffers_settings_receives(tmp_path):
    stop = threading.Event()
    with PtyLine(SC, SC.line, seed=3) as line:
        line.link(str(tmp_path / "line0"))
        player = threading.Thread(target=line.play, args=(stop,), daemon=True)
        player.start()
        fd, _, _ = open_read_only(str(tmp_path / "line0"), SC.line, marks=True)
        try:
            right = _read_for(fd, 0.6)
            configure(fd, LineSettings(19200, "O", 1), pty=True, marks=True)
            time.sleep(0.05)
            odd = _read_for(fd, 0.6)
        finally:
            os.close(fd)
            stop.set()
            player.join(5)
        assert line.bytes_received_from_sniffer == 0  # nothing came back from the sniffer's end
    assert not (tmp_path / "line0").exists()  # the link goes with the line
    data, marks = MarkReader().feed(right)
    sent = b"".join(f.raw for f in simulate(SC, SC.line, 5.0, 3))
    assert len(data) > 200 and not marks
    assert data[20:-20] in sent  # (the first and last bytes may belong to frames cut by the start or end)
    data, marks = MarkReader().feed(odd)
    assert len(marks) >= 0.9 * len(data) > 100  # the wrong parity: (nearly) every byte a parity error


def test_simulate_receiver_settings_record_what_that_uart_received(tmp_path):
    from sniffer.cli import main
    from sniffer.formats.mcap.reader import open_mcap, read_frames

    out = tmp_path / "odd.mcap"
    assert main(["simulate", "--out", str(out), "--duration", "1", "--adapter", "wire",
                 "--receiver-parity", "O"]) == 0
    info, _ = open_mcap(str(out))
    assert (info.baud, info.parity) == (19200, "O") and info.extra["simulated_line"] == "19200 8E1"
    records = read_frames(str(out))
    frames = [r for r in records if r["protocol"] != "noise"]
    assert frames and all(crc_ok(bytes.fromhex(r["raw"])) for r in frames)  # data bits right...
    assert all(any(a["code"] == "uart.parity_error" for a in r["annotations"]) for r in records)  # ...all flagged
    # and a CRC over bytes the UART flagged proves nothing: the frames are cut, but not taken as good
    assert all(r["crc_ok"] is False and any(a["code"] == "modbus.crc.unproven" for a in r["annotations"])
               for r in frames)
    csv = tmp_path / "slow.csv"
    assert main(["simulate", "--out", str(csv), "--duration", "1", "--receiver-baud", "9600"]) == 0
    assert main(["replay", str(csv), "--baud", "9600", "--parity", "E", "--format", "jsonl"]) == 0


def test_simulate_pty_refuses_a_path_that_is_not_its_link(tmp_path, capsys):
    from sniffer.cli import main

    taken = tmp_path / "taken"
    taken.write_text("x")
    assert main(["simulate", "--pty", str(taken)]) == 2
    assert "exists; give a free path" in capsys.readouterr().err
    assert taken.read_text() == "x"
