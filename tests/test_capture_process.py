"""Issue 11: the UI never harms the capture.  `sniffer live` with its TUI on a real terminal (a pty) runs
the capture as a process of its own; the TUI only views it.

Each test runs the real command in a pseudo-terminal as a user would, and a simulated line (PtyBus, played
from this process) on a second pty as the port.  Checked: what arrived and who holds the port, not when;
the one timing figure compared (responses whose request and answer came in one read, so no latency) is a
count with a wide margin, between two runs of the same feed on this machine.
"""

from __future__ import annotations

import os
import resource
import signal
import sys
import threading
import time

from terminal import Terminal, children, descendants, fds_on, stat_fields

from sniffer.simulator.bus import simulate
from sniffer.simulator.ptybus import PtyBus
from sniffer.simulator.scenario import get_scenario
from sniffer.formats.mcap.reader import open_mcap, read_frames
from sniffer.sources.reader_priority import READER_RT_PRIORITY

HANG_S = 60.0


def _timing(path) -> tuple[int, int, int]:
    """(responses, responses without latency, responses timed before their request ends) of a capture."""
    recs = read_frames(str(path))
    by = {r["index"]: r for r in recs}
    rsp = [r for r in recs if r.get("role") == "response"]
    nolat = sum(r.get("latency_ms") is None for r in rsp)
    before = sum(1 for r in rsp if r.get("pair") in by and r["t"] < by[r["pair"]].get("t_end", by[r["pair"]]["t"]))
    return len(rsp), nolat, before


def _feed(scenario: str, seconds: float):
    sc = get_scenario(scenario)
    return sc, list(simulate(sc, sc.line, seconds, seed=3))


def _live_argv(port: str, line, out) -> list[str]:
    """`sniffer live` on `port` with `line`'s settings, recording to `out` (its TUI on unless told)."""
    return [sys.executable, "-m", "sniffer", "live", port, "--baud", str(line.baud), "--parity", line.parity,
            "--stopbits", str(line.stopbits), "--out", str(out)]


def _run_live(tmp_path, name: str, frames, line, *, tui: bool, prefix: tuple = ()):
    """Play `frames` to `sniffer live` (its TUI on a terminal, or headless; `prefix`: a command it runs under)
    and return (MCAP, bytes written back, what the terminal showed)."""
    out = tmp_path / f"{name}.mcap"
    with PtyBus() as bus:
        argv = [*prefix, *_live_argv(bus.port, line, out)]
        term = Terminal(argv if tui else argv + ["--headless", "--quiet"])
        try:
            # the port is open once the capture publishes (TUI: the App shows its label) or says so
            assert term.wait_for(bus.port), term.screen[-2000:]
            deadline = time.monotonic() + HANG_S
            while not any(fds_on(p, bus.port) for p in [term.proc.pid, *descendants(term.proc.pid)]):
                assert time.monotonic() < deadline, "the port was never opened"
                time.sleep(0.05)
            tree = [term.proc.pid, *descendants(term.proc.pid)]
            holders = [p for p in tree if fds_on(p, bus.port)]
            # the capture's process: the command itself (headless), or the TUI's child that runs live
            capture = term.proc.pid if not tui else next(p for p in children(term.proc.pid) if p not in holders)
            readers = children(capture)
            stats = {}
            player = threading.Thread(target=lambda: stats.update(s=bus.play(frames)))
            player.start()
            while player.is_alive():
                term.read()
            time.sleep(0.5)  # the last answer reaches the capture
            policies = {p: _policies(p) for p in tree}
            if tui:
                term.type("q")
                assert term.wait_for("Stop the live capture"), "quitting a live capture did not ask"
                term.type("y")
            else:
                os.kill(term.proc.pid, signal.SIGINT)
        finally:
            rc = term.finish()
        bus.drain()
        assert rc == 0, term.screen[-3000:]
        assert stats["s"].frames == len(frames)
        # the port is read by a process of the capture's own (processes/reader.py), never by the capture's
        # process, whose decoding thread would hold the interpreter the reader waits for
        assert capture not in holders and holders and all(h in readers for h in holders), (capture, holders)
        return out, bus.bytes_received_from_sniffer, term, holders, policies


SCHED_OTHER, SCHED_FIFO = 0, 1


def _realtime_allowed() -> bool:
    """Whether this user may ask for SCHED_FIFO (sources/reader_priority.py): root, or an rtprio limit."""
    return os.geteuid() == 0 or resource.getrlimit(resource.RLIMIT_RTPRIO)[0] >= READER_RT_PRIORITY


def _policies(pid: int) -> dict[str, tuple[int, int]]:
    """Thread name/id -> (scheduling policy, nice level) of a process's threads (/proc/PID/task/TID)."""
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            name = open(f"/proc/{pid}/task/{tid}/comm").read().strip()
            policy = next(int(line.split()[-1]) for line in open(f"/proc/{pid}/task/{tid}/sched")
                          if line.startswith("policy"))
            fields = stat_fields(pid, tid)
        except (OSError, StopIteration):  # a thread that ended meanwhile
            continue
        if fields is not None:
            out[f"{name}/{tid}"] = (policy, int(fields[16]))  # field 19 of stat: nice
    return out


def test_tui_capture_runs_in_its_own_process_and_records_as_headless(tmp_path):
    """The same a510 line at 19200 played twice: with the TUI open, then headless.  Both record every byte; the
    TUI's process never holds the port (its capture child does); the recorded timing is no worse with the TUI
    (before issue 11: 10 % of responses without latency with the TUI, 0 headless)."""
    sc, frames = _feed("a510", 20.0)
    figures = {}
    for name, tui in (("tui", True), ("headless", False)):
        out, written_back, term, holders, policies = _run_live(tmp_path, name, frames, sc.line, tui=tui)
        assert written_back == 0  # passive: nothing reached the bus, TUI or not
        assert [r["raw"] for r in read_frames(str(out))] == [f.raw.hex() for f in frames]
        if tui:
            assert holders and term.proc.pid not in holders, "the TUI's own process opened the port"
            # the viewer leaves the CPU to the capture: nice 19 (not SCHED_IDLE, see tui/run.py yield_to_capture),
            # its threads started after the first ones included; the capture at this test's own priority
            viewer, own = policies[term.proc.pid], os.nice(0)
            assert viewer[f"python/{term.proc.pid}"] == (SCHED_OTHER, 19), viewer
            assert sum(p == (SCHED_OTHER, 19) for p in viewer.values()) >= 3, viewer  # the App's, the feed's
            # the capture at this test's own priority, but for its reader: real-time where allowed
            capture = sorted(p for h in holders for p in policies[h].values())
            rt = [(SCHED_FIFO, own)] if _realtime_allowed() else []  # its nice: the process's, as inherited
            assert capture == [(SCHED_OTHER, own)] * (len(capture) - len(rt)) + rt, policies
            assert b"frames" in term.screen and f"{len(frames)} frames".encode() in term.screen  # the summary
        else:
            assert len(holders) == 1 and term.proc.pid not in holders
        reader = open_mcap(str(out))[0].extra["reader"]  # what the reader got, in the capture's metadata
        if _realtime_allowed():
            assert reader == {"policy": "SCHED_FIFO", "priority": READER_RT_PRIORITY}, reader
        else:
            assert reader["policy"] == "normal" and reader["why"], reader
        figures[name] = _timing(out)
    (n, tui_nolat, tui_before), (_, head_nolat, head_before) = figures["tui"], figures["headless"]
    assert n > 300
    margin = 3 + n // 20  # 5 %: the scheduler of a loaded machine, not the TUI (which cost 10 % before)
    assert tui_nolat <= head_nolat + margin and tui_before <= head_before + margin, figures


def test_a_reader_refused_a_realtime_priority_records_all_the_same(tmp_path):
    """Where the system grants no real-time priority (no CAP_SYS_NICE, RLIMIT_RTPRIO 0: a normal user's
    default), the capture's reader stays a normal thread, says why in the capture's metadata, and records
    every frame."""
    sc, frames = _feed("a510", 4.0)
    no_caps = ["setpriv", "--bounding-set", "-sys_nice", "--inh-caps", "-sys_nice"] if os.geteuid() == 0 else []
    out, written_back, _, holders, policies = _run_live(tmp_path, "normal", frames, sc.line, tui=False,
                                                        prefix=(*no_caps, "prlimit", "--rtprio=0:0"))
    assert written_back == 0
    assert [r["raw"] for r in read_frames(str(out))] == [f.raw.hex() for f in frames]
    assert all(p[0] == SCHED_OTHER for h in holders for p in policies[h].values()), policies
    reader = open_mcap(str(out))[0].extra["reader"]
    assert reader == {"policy": "normal", "why": "Operation not permitted"}, reader


def test_the_realtime_priority_can_be_declined(tmp_path):
    """SNIFFER_REALTIME=off: the reader stays a normal thread even where the system would grant it (root
    here), says so in the capture's metadata, and the TUI's capture process inherits the setting."""
    sc, frames = _feed("a510", 3.0)
    for name, tui in (("declined-headless", False), ("declined-tui", True)):
        out, written_back, _, holders, policies = _run_live(tmp_path, name, frames, sc.line, tui=tui,
                                                            prefix=("env", "SNIFFER_REALTIME=off"))
        assert written_back == 0
        assert [r["raw"] for r in read_frames(str(out))] == [f.raw.hex() for f in frames]
        assert holders and all(p[0] == SCHED_OTHER for h in holders for p in policies[h].values()), policies
        reader = open_mcap(str(out))[0].extra["reader"]
        assert reader == {"policy": "normal", "why": "declined (SNIFFER_REALTIME=off)"}, reader


def test_tui_on_a_missing_port_says_one_line(tmp_path):
    """The capture process fails before the UI starts: its one line on the terminal, its exit status."""
    term = Terminal([sys.executable, "-m", "sniffer", "live", str(tmp_path / "ttyNONE"), "--baud", "9600",
                     "--out", str(tmp_path / "x.mcap")])
    rc = term.finish()
    text = term.screen.decode(errors="replace")
    assert rc != 0 and "Traceback" not in text
    assert [ln for ln in text.splitlines() if "error" in ln] == [ln for ln in text.splitlines() if ln.strip()][-1:]
    assert "ttyNONE" in text and not (tmp_path / "x.mcap").exists()


def test_a_terminal_gone_without_sighup_ends_the_tui_and_keeps_the_capture(tmp_path):
    """The TUI's pty closes under it and no SIGHUP comes (the pty is not its controlling terminal, as for a
    command another program started): the TUI quits as on SIGHUP instead of spinning, and the live capture
    under it is stopped as Ctrl-C stops it, its MCAP closed with what it recorded."""
    out = tmp_path / "gone.mcap"
    sc, frames = _feed("a510", 3.0)
    with PtyBus() as bus:
        term = Terminal(_live_argv(bus.port, sc.line, out))
        try:
            assert term.wait_for(bus.port), term.screen[-2000:]
            player = threading.Thread(target=bus.play, args=(frames,))
            player.start()
            while player.is_alive():
                term.read()
            term.read(0.5)  # the last answer reaches the capture
            os.close(term.master)  # the terminal's window closed
            term.proc.wait(HANG_S)
        finally:
            if term.proc.poll() is None:
                term.proc.kill()
                term.proc.wait()
        bus.drain()
    assert term.proc.returncode is not None
    assert not list(tmp_path.glob("*.part")), "the capture was not closed"
    assert [r["raw"] for r in read_frames(str(out))] == [f.raw.hex() for f in frames]
