"""`sniffer detect`'s search on a simulated port with a virtual clock: the real listen loop, windows, evidence
and verdicts against lines whose settings we know, the same way every run (no pty, no waiting)."""

from __future__ import annotations

import dataclasses

import pytest

from sniffer.capture.busfile import load_bus_file
from sniffer.detect.candidates import COMMON_BAUDS, baud_order, fmt_of, parse_bauds, setting
from sniffer.detect.listen import listen
from sniffer.detect.report import bus_file, headline, table
from sniffer.detect.search import Search
from sniffer.line import SettingsError
from sniffer.capture.settings import CaptureSpec
from sniffer.simulator import get_scenario
from sniffer.simulator.simport import SimulatedPort


def detect(scenario: str, line: str | None = None, resync: str = "edge", bauds=(), **kw):
    sc = get_scenario(scenario)
    if line is not None:
        b, f = line.split()
        sc_line = setting(int(b), f)
    else:
        sc_line = sc.line
    port = SimulatedPort(sc, sc_line, resync=resync, start_s=0.137)
    verdict = listen(port, Search(baud_order(tuple(bauds)), quiet_s=kw.pop("quiet_s", 5.0)), **kw)
    return verdict, port


def settled(v) -> tuple[str, str]:
    """The settings the verdict names (a listen at 8E1 names 8E2 when its characters come 12 bits apart)."""
    return f"{v.best.line.baud} {fmt_of(v.best.line)}", v.best.best.protocol


@pytest.mark.parametrize("scenario, line, protocol", [
    ("default", "19200 8E1", "modbus-rtu"),  # even parity
    ("default", "9600 8O1", "modbus-rtu"),  # odd
    ("default", "38400 8N1", "modbus-rtu"),  # none
    ("tds-v8", "9600 8N2", "modbus-rtu"),  # 2 stop bits: told from 8N1 by the characters' spacing
    ("errors", "57600 8E1", "modbus-rtu"),  # CRC errors, timeouts, noise on the line
    ("stress", "230400 8N1", "modbus-rtu"),  # never silent for t3.5; 255-byte frames to time
    ("a510-ascii", "9600 7E1", "modbus-ascii"),
    ("spl-ascii", "19200 7N2", "modbus-ascii"),
    ("a510-ascii", "38400 8N1", "modbus-ascii"),  # ASCII on 8 bits
    ("pd-series", "9600 8N1", "pd-rtu"),
    ("pd-series-ascii", "4800 8O1", "pd-ascii"),
    ("default", "1200 8E1", "modbus-rtu"),
    ("default", "19200 8E2", "modbus-rtu"),  # 2 stop bits after a parity bit: received alike at 8E1, timed apart
    ("default", "9600 8O2", "modbus-rtu"),
    ("a510-ascii", "9600 7E2", "modbus-ascii"),
])
def test_each_line_is_found_certain(scenario, line, protocol):
    v, port = detect(scenario, line)
    assert v.status == "certain", headline(v, "sim")
    assert settled(v) == (line, protocol)
    assert v.best.errors == 0 and v.best.timing in ("exact", "?")
    assert port.configured[-1] == v.best.rx  # it ended listening at the answer (or at its twin: received alike)
    assert v.best.line.stopbits == int(line[-1]) and f"{line} {protocol} (certain" in headline(v, "sim")


def test_a_uart_that_takes_a_low_stop_bit_for_a_start_bit_is_found_by_the_second_sweep():
    # read at 8N1, an 8E1 line garbles after every framing error on such a UART: nothing frames
    v, port = detect("default", "19200 8E1", resync="16550")
    assert settled(v) == ("19200 8E1", "modbus-rtu") and v.status == "certain"
    n8n1 = next(w for w in v.windows if (w.rx.baud, w.fmt) == (19200, "8N1"))
    assert not n8n1.found


def test_8n1_and_8n2_are_told_apart_by_timing_only():
    v, _ = detect("tds-v8", "9600 8N2")
    n1 = next(w for w in v.windows if w.fmt == "8N1" and w.rx.baud == 9600)
    assert n1.errors == 0 and n1.fits  # a UART reads 8N2 at 8N1 without an error...
    assert n1.timing == "slower" and n1.hint == "8N2"  # ...but the characters come 11 bits apart
    v, _ = detect("default", "9600 8N1")
    assert settled(v) == ("9600 8N1", "modbus-rtu")
    assert all(w.timing == "impossible" for w in v.windows if w.fmt == "8N2" and w.rx.baud == 9600)


@pytest.mark.parametrize("scenario, line", [("tds-v8", "460800 8N2"), ("fast", "115200 8N1")])
def test_stop_bits_left_open_when_the_timing_cannot_be_measured(scenario, line):
    # short frames at a high rate: a frame takes one or two 1 ms USB packets, no spacing to measure
    v, _ = detect(scenario, line)
    assert v.status == "stop bits" and v.settled
    baud = line.split()[0]
    assert settled(v) == (f"{baud} 8N1", "modbus-rtu")  # 1 stop bit: a UART set so reads both alike
    assert [f"{r.rx.baud} {r.fmt}" for r in v.rivals] == [f"{baud} 8N2"]
    assert "stop bits not told apart" in headline(v, "sim")


@pytest.mark.parametrize("scenario, line", [("default", "921600 8O1"), ("fast", "115200 8E2"),
                                            ("default", "250000 8E1")])
def test_stop_bits_after_a_parity_bit_left_open_when_the_timing_cannot_be_measured(scenario, line):
    """8E1 and 8E2 receive alike: without the characters' spacing, never "certain" of either."""
    v, _ = detect(scenario, line, bauds=(int(line.split()[0]),))
    assert v.status == "stop bits" and v.settled and not v.best.certain
    fmt = line.split()[1]
    assert settled(v) == (f"{line.split()[0]} {fmt[:2]}1", "modbus-rtu")  # 1 stop bit: a UART reads both so
    assert f"a UART receives {fmt[:2]}1 and {fmt[:2]}2 alike" in headline(v, "sim")


def load_bus_text(tmp_path, text: str):
    path = tmp_path / "line.toml"
    path.write_text(text)
    return load_bus_file(str(path))


def test_the_character_time_names_the_stop_bits_a_listen_cannot(tmp_path):
    """An 8E2 line heard at 8E1 (no UART error: a UART checks one stop bit): 12 bits a character, so 8E2,
    in the verdict, the table and the bus file; an 8E1 line stays 8E1."""
    v, _ = detect("default", "19200 8E2")
    ev = v.best
    assert (ev.fmt, fmt_of(ev.line), ev.timing) == ("8E1", "8E2", "exact") and ev.bits_per_char > 11.7
    assert v.status == "certain" and "19200 8E2 modbus-rtu (certain" in headline(v, "sim")
    assert table(v)[1].endswith("certain as 8E2")
    assert load_bus_text(tmp_path, bus_file(v, "/dev/ttyUSB0")).stopbits == 2
    v, _ = detect("default", "19200 8E1")
    assert (fmt_of(v.best.line), v.status) == ("8E1", "certain") and v.best.bits_per_char < 11.7


def test_a_rate_not_tried_fits_nothing_until_asked_for():
    v, _ = detect("default", "250000 8E1", max_s=30)
    assert v.status == "none" and not v.settled
    assert "no candidate fits" in headline(v, "sim")
    v, _ = detect("default", "250000 8E1", bauds=parse_bauds(["250000"]))
    assert settled(v) == ("250000 8E1", "modbus-rtu") and {w.rx.baud for w in v.windows} == {250000}  # first


def test_silent_line_is_no_traffic():
    silent = dataclasses.replace(get_scenario("default"), name="silent", units=(), polls=())
    port = SimulatedPort(silent, silent.line)
    v = listen(port, Search(COMMON_BAUDS, quiet_s=3.0))
    assert v.status == "no traffic" and v.best is None
    assert len(v.windows) == 1 and v.windows[0].seconds == pytest.approx(3.0, abs=0.06)
    assert "no traffic" in headline(v, "/dev/ttyUSB9")


def test_units_and_poll_periods_from_a_longer_listen():
    v, _ = detect("tds-v8", "9600 8N2", follow_s=2.0)
    assert v.status == "certain" and v.best.seconds > 2.0 and v.decided_s < v.best.seconds + 2
    assert [u.unit for u in v.best.units] == [1, 2]
    assert all(0.19 < u.period_s < 0.21 for u in v.best.units)  # the scenario polls every 200 ms
    assert {0x03, 0x06} <= set(v.best.units[0].functions)


def test_report_table_best_first_and_bus_file_that_live_takes(tmp_path):
    v, _ = detect("a510-ascii", "9600 7E1", follow_s=1.0)
    rows = table(v)
    assert rows[0].split()[:2] == ["setting", "protocol"]
    assert rows[1].split()[:3] == ["9600", "7E1", "modbus-ascii"] and rows[1].endswith("certain")
    path = tmp_path / "line.toml"
    path.write_text(bus_file(v, "/dev/ttyUSB0"))
    bus = load_bus_file(str(path))
    assert (bus.baud, bus.parity, bus.stopbits, bus.databits, bus.protocol) == (9600, "E", 1, 7, "modbus-ascii")
    assert bus.devices == {}  # bus_file without the models named: the units are comments (generic)
    assert "# 1 = \"generic\"" in path.read_text()
    resolved = CaptureSpec.of(bus_file=str(path)).resolve(None)
    assert resolved.line.label() == "9600 7E1" and resolved.protocol.name == "modbus-ascii"


def test_bauds_flag():
    assert parse_bauds(["250000,31250", "250000 76800"]) == (250000, 31250, 76800)
    assert baud_order((31250,))[:2] == (31250, 9600)
    for bad, why in (("x", "not a whole number"), ("10", "outside"), ("9999999", "outside")):
        with pytest.raises(SettingsError, match=why):
            parse_bauds([bad])


class BusyHost(SimulatedPort):
    """A port read by a host that wakes late from idle: the first read after a silence often comes `late_ns`
    after its data, and the reads due meanwhile with it (a loaded laptop, a virtual CPU waking up, a pty whose
    writer stalled). The frame's first timed read is late, the later ones not: its measured time is squeezed."""

    def __init__(self, *a, late_ns: int = 2_000_000, share: float = 0.5, **kw) -> None:
        import random

        super().__init__(*a, **kw)
        self.rng, self.late_ns, self.share = random.Random(7), late_ns, share
        self.stall_until = self.last = 0

    def read(self, timeout_s: float) -> bytes:
        idle = self.t - self.last
        data = super().read(timeout_s)
        if data:
            if idle > 5_000_000 and self.rng.random() < self.share:  # woke from idle: late
                self.stall_until = self.t + self.late_ns
            self.t = self.last = max(self.t, self.stall_until)
        return data


def test_a_host_that_wakes_late_never_makes_the_line_too_fast():
    """Late reads squeeze most frames' measured character time below 8N1's 10 bits; the line is still found
    (as 8N1: the frames a late read squeezed least are 10 bits), and 8N2 still impossible."""
    sc = get_scenario("pd-series")
    port = BusyHost(sc, setting(9600, "8N1"), start_s=0.137)
    v = listen(port, Search(baud_order(()), quiet_s=5.0))
    assert settled(v) == ("9600 8N1", "pd-rtu"), headline(v, "sim")
    n1 = next(w for w in v.windows if w.fmt == "8N1" and w.rx.baud == 9600)
    assert n1.bits_per_char < 10 * 0.93  # squeezed: the old verdict called it impossible
    assert n1.timing != "impossible"
    assert all(w.timing == "impossible" for w in v.windows if w.fmt == "8N2" and w.rx.baud == 9600)


def named_detect(scenario: str, line: str | None = None, **kw):
    from sniffer.detect.models import Naming

    naming = Naming()
    v, port = detect(scenario, line, follow_s=kw.pop("follow_s", 1.0), more=naming.wants_more,
                     more_s=kw.pop("more_s", 30.0), **kw)
    return v, naming.feed(v.best.answers, v.best.best.protocol)


@pytest.mark.parametrize("scenario, models", [
    ("tds-v8", {1: "tds-v8", 2: "tds-v8"}),
    ("a510-ascii", {1: "a510", 2: "a510"}),
    ("spl", {1: "spl", 2: "spl"}),
    ("pd-series", {1: "pd-series", 2: "pd-series"}),  # the protocol is the model's own
])
def test_the_bus_file_names_the_models_identified_while_listening(tmp_path, scenario, models):
    from sniffer.simulator import get_scenario

    v, named = named_detect(scenario)
    assert v.status in ("certain", "stop bits") and {u: n.model for u, n in named.items()} == models
    assert all(get_scenario(scenario).devices.get(u) == m for u, m in models.items())  # what the line really is
    text = bus_file(v, "/dev/ttyUSB0", named)
    bus = load_bus_text(tmp_path, text)
    assert bus.devices == models  # a table live --bus applies as it is: every model's decoding kept
    assert "generic" not in text and "model not identified" not in text


def test_units_of_no_known_model_are_named_on_stderr_and_left_as_comments(tmp_path):
    """The default scenario's drives are generic Modbus devices: nothing names them, the listen stops once their
    answers bring nothing new (well before --identify-time), and the bus file leaves them to the user."""
    from sniffer.detect.report import unnamed_line

    v, named = named_detect("default", "19200 8E1", more_s=120.0)
    assert named == {}
    assert v.best.seconds < 30  # stopped when the polls repeated, not at the 120 s allowed
    line = unnamed_line(v.best, named)
    assert line.startswith("model not identified for units 1, 2, 5")
    text = bus_file(v, "/dev/ttyUSB0", named)
    assert load_bus_text(tmp_path, text).devices == {}
    assert '# 1 = "generic"' in text and "model not identified" in text


def test_a_mixed_line_names_the_units_it_can_and_comments_the_rest(tmp_path):
    """Named units in [units], the unnamed ones commented right after them (uncommenting one adds it there)."""
    from sniffer.detect.models import Named

    v, _ = named_detect("default", "19200 8E1", more_s=0.0)
    named = {1: Named("tds-v8", 0.9, "test")}
    text = bus_file(v, "/dev/ttyUSB0", named)
    assert load_bus_text(tmp_path, text).devices == {1: "tds-v8"}
    uncommented = text.replace('# 2 = "generic"', '2 = "generic"')
    assert load_bus_text(tmp_path, uncommented).devices == {1: "tds-v8", 2: "generic"}
