"""`sniffer extcap`: Wireshark's extcap interface, driven by the real tshark on a simulated line (a pty).

The launcher is installed into a personal extcap folder (HOME is the test's folder, so `tshark -G folders`
names one there); tshark lists the line, runs the capture through the launcher and stops it (its
`-a duration`), and the pcapng it wrote decodes as Modbus RTU with our comment on every packet."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest
from helpers import SimulatedLine

from sniffer.formats.pcap.format import TSHARK_ARGS

pytestmark = pytest.mark.skipif(shutil.which("tshark") is None,
                                reason="tshark not installed (scripts/install-system-deps.sh installs it)")
SNIFFER = [sys.executable, "-m", "sniffer"]


def _env(home) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("XDG_")}
    return {**env, "HOME": str(home)}


def _sniffer(*args, home) -> subprocess.CompletedProcess:
    return subprocess.run([*SNIFFER, *args], capture_output=True, text=True, timeout=120, env=_env(home))


def _pref(value: str, name: str, setting: str) -> list[str]:
    """tshark's -o for an extcap interface's dialog value (Wireshark names it extcap.<interface>.<flag>)."""
    iface = "".join(c if c.isalnum() else "_" for c in value.lower())
    return ["-o", f"extcap.{iface}.{name}:{setting}"]


def _install(tmp_path, *extra) -> str:
    r = _sniffer("extcap", "--install", "--no-sigrok", *extra, home=tmp_path)
    assert r.returncode == 0, r.stderr
    launcher = r.stderr.split("wrote ", 1)[1].split(":", 1)[0]
    assert launcher.startswith(str(tmp_path)) and os.access(launcher, os.X_OK)
    return launcher


def _tshark_capture(tmp_path, value: str, seconds: int, *prefs: str, packets: int | None = None
                    ) -> tuple[subprocess.CompletedProcess, str]:
    """tshark's capture of `value` for `seconds`, or until `packets` are in where given (`-c`: the test needs no
    more, and `seconds` only bounds a capture that never gets them)."""
    out = str(tmp_path / "out.pcapng")
    count = ["-c", str(packets)] if packets else []
    r = subprocess.run(["tshark", "-i", value, *prefs, "-a", f"duration:{seconds}", *count, "-w", out],
                       capture_output=True, text=True, timeout=180, env=_env(tmp_path))
    return r, out


def _packets(path: str) -> list[list[str]]:
    r = subprocess.run(["tshark", "-r", path, *TSHARK_ARGS, "-T", "fields", "-E", "separator=|",
                        "-e", "frame.protocols", "-e", "mbrtu.unit_id", "-e", "frame.comment"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return [line.split("|") for line in r.stdout.splitlines()]


def _left_running(marker: str) -> list[str]:
    """Command lines of processes still running that mention `marker` (a capture that did not stop)."""
    left = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if marker in cmd and "--capture" in cmd:
            left.append(cmd)
    return left


def test_the_extcap_sentences(tmp_path):
    r = _sniffer("extcap", "--extcap-interfaces", "--extcap-version=4.0", "--no-sigrok", "--list-port", "COM7",
                 "--list-port", "socket://10.0.0.7:4001", home=tmp_path)
    assert r.returncode == 0 and r.stderr == ""
    lines = r.stdout.splitlines()
    assert lines[0].startswith("extcap {version=")
    assert "interface {value=rs485:COM7}" in r.stdout and "interface {value=rs485:socket://10.0.0.7:4001}" in r.stdout
    r = _sniffer("extcap", "--extcap-dlts", "--extcap-interface", "rs485:COM7", home=tmp_path)
    assert r.stdout.startswith("dlt {number=147}")
    r = _sniffer("extcap", "--extcap-config", "--extcap-interface", "rs485:COM7", home=tmp_path)
    calls = [x.split("{call=")[1].split("}")[0] for x in r.stdout.splitlines() if x.startswith("arg ")]
    assert calls == ["--line-baud", "--line-parity", "--line-stopbits", "--line-bus"]
    defaults = [x for x in r.stdout.splitlines() if "{default=true}" in x]
    assert all("{value=detect}" in x for x in defaults) and len(defaults) == 3
    r = _sniffer("extcap", "--extcap-config", "--extcap-interface", "nothing:here", home=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "not an interface" in r.stderr


def test_tshark_captures_a_simulated_line_with_our_comments(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1") as line:
        _install(tmp_path, "--list-port", line.path)
        value = f"rs485:{line.path}"
        listed = subprocess.run(["tshark", "-D"], capture_output=True, text=True, timeout=120, env=_env(tmp_path))
        assert value in listed.stdout
        r, out = _tshark_capture(tmp_path, value, 5, *_pref(value, "linebaud", "19200"),
                                 *_pref(value, "lineparity", "E"), *_pref(value, "linestopbits", "1"))
        written = line.pty.bytes_received_from_sniffer
    assert r.returncode == 0 and "Error" not in r.stderr, r.stderr
    assert written == 0  # passive
    assert not _left_running(str(tmp_path))  # the capture stopped with tshark
    packets = _packets(out)
    assert len(packets) > 50
    modbus = [p for p in packets if "mbrtu" in p[0]]
    assert len(modbus) >= 0.9 * len(packets) and {p[1] for p in modbus} >= {"1"}  # Wireshark's own dissector
    assert all(p[2].startswith("rs485-sniffer #") for p in packets)  # a comment on every packet
    assert any("answers #" in p[2] for p in packets) and any("CRC ok" in p[2] for p in packets)
    assert all("time per read" in p[2] for p in packets)  # how the time was taken


def test_detect_is_the_default(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1") as line:
        _install(tmp_path, "--list-port", line.path)
        # the line's settings found first (detect), then packets: 40 s bounds the two on a loaded machine
        r, out = _tshark_capture(tmp_path, f"rs485:{line.path}", 40, packets=30)
        written = line.pty.bytes_received_from_sniffer
    assert r.returncode == 0 and "Error" not in r.stderr, r.stderr
    assert written == 0
    packets = _packets(out)
    assert len(packets) > 20 and sum("mbrtu" in p[0] for p in packets) >= 0.9 * len(packets)


def test_a_port_that_is_not_there_is_one_line_in_tshark(tmp_path):
    missing = str(tmp_path / "ttyUSB9")
    _install(tmp_path, "--list-port", missing)
    value = f"rs485:{missing}"
    r, _ = _tshark_capture(tmp_path, value, 5, *_pref(value, "linebaud", "9600"), *_pref(value, "lineparity", "N"),
                           *_pref(value, "linestopbits", "1"))
    assert "no such port" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not _left_running(str(tmp_path))


def test_a_bus_files_links_are_the_interfaces_of_one_capture(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1", name="a") as a, \
            SimulatedLine(tmp_path, "default", "19200 8E1", name="b", seed=9) as b:
        bus = tmp_path / "plant.toml"
        bus.write_text(f'[serial]\nbaud = 19200\nparity = "E"\n\n[[links]]\nname = "drives"\nport = "{a.path}"\n\n'
                       f'[[links]]\nname = "pumps"\nport = "{b.path}"\n')
        _install(tmp_path, "--list-bus", str(bus))
        value = f"rs485-bus:{bus}"
        listed = subprocess.run(["tshark", "-D"], capture_output=True, text=True, timeout=120, env=_env(tmp_path))
        assert value in listed.stdout and "(drives, pumps)" in listed.stdout
        r, out = _tshark_capture(tmp_path, value, 6)
        written = a.pty.bytes_received_from_sniffer + b.pty.bytes_received_from_sniffer
    assert r.returncode == 0 and "Error" not in r.stderr, r.stderr
    assert written == 0
    names = subprocess.run(["tshark", "-r", out, "-T", "fields", "-e", "frame.interface_name"], capture_output=True,
                           text=True, timeout=120).stdout.split("\n")
    assert {n.split(" ")[0] for n in names if n} == {"drives", "pumps"}  # each link an interface
    packets = _packets(out)
    assert len(packets) > 50 and all(p[2].startswith("rs485-sniffer #") for p in packets)


def _two_link_bus(tmp_path, a: str, b: str):
    bus = tmp_path / "plant.toml"
    bus.write_text(f'[serial]\nbaud = 19200\nparity = "E"\n\n[[links]]\nname = "drives"\nport = "{a}"\n\n'
                   f'[[links]]\nname = "pumps"\nport = "{b}"\nbaud = 9600\n')
    return bus


def test_each_link_of_a_bus_file_is_an_interface_too(tmp_path):
    from sniffer.capture.settings import CaptureSpec
    from sniffer.cli import build_parser
    from sniffer.extcap.capture import detect_argv, live_argv
    from sniffer.extcap.interfaces import Target

    bus = _two_link_bus(tmp_path, "/dev/ttyUSB1", "/dev/ttyUSB2")
    plain = tmp_path / "line.toml"
    plain.write_text('[serial]\nbaud = 9600\n')
    r = _sniffer("extcap", "--extcap-interfaces", "--no-sigrok", "--list-bus", str(bus), "--list-bus", str(plain),
                 home=tmp_path)
    assert r.returncode == 0 and r.stderr == ""
    shown = dict(x[len("interface {value="):-1].split("}{display=") for x in r.stdout.splitlines()
                 if x.startswith("interface {value=") and "rs485-" in x)
    assert shown == {
        f"rs485-bus:{bus}": "RS-485 Modbus: bus file plant.toml (drives, pumps)",  # the whole file: all links
        f"rs485-link:{bus}#drives": "RS-485 Modbus: plant.toml: drives (ttyUSB1)",
        f"rs485-link:{bus}#pumps": "RS-485 Modbus: plant.toml: pumps (ttyUSB2)",
        f"rs485-bus:{plain}": "RS-485 Modbus: bus file line.toml",  # no [[links]]: one interface
    }
    value = f"rs485-link:{bus}#pumps"
    assert Target.parse(value) == Target("link", str(bus), "pumps") and Target.parse(value).value == value
    r = _sniffer("extcap", "--extcap-dlts", "--extcap-interface", value, home=tmp_path)
    assert r.returncode == 0 and r.stdout.startswith("dlt {number=147}")
    r = _sniffer("extcap", "--extcap-config", "--extcap-interface", value, home=tmp_path)
    calls = [x.split("{call=")[1].split("}")[0] for x in r.stdout.splitlines() if x.startswith("arg ")]
    assert calls == ["--line-baud", "--line-parity", "--line-stopbits"]  # the interface is its bus file

    odd = Target("link", "/x/a#b.toml", "pump#2%")  # a '#' in the file's path or the link's name reads back
    assert odd.value == "rs485-link:/x/a#b.toml#pump%232%25" and Target.parse(odd.value) == odd
    target = Target.parse(value)
    assert detect_argv(target, "detect", "detect", "detect", None, "x.toml") is None  # the bus file says
    argv = live_argv(target, "detect", "detect", "detect", None, None)
    assert argv[:3] == ["live", "--bus", str(bus)] and "--only-link=pumps" in argv
    spec = CaptureSpec.from_args(build_parser().parse_args(argv))
    assert [(p.name, p.ports) for p in spec.links] == [("pumps", ("/dev/ttyUSB2",))]
    assert spec.resolve_link("pumps", need_baud=False).line.baud == 9600  # its own table's settings
    whole = CaptureSpec.from_args(build_parser().parse_args(live_argv(Target("bus", str(bus)), "detect", "detect",
                                                                                 "detect", None, None)))
    assert [p.name for p in whole.links] == ["drives", "pumps"]


def test_only_link_names_a_link_of_the_bus_file(tmp_path):
    bus = _two_link_bus(tmp_path, str(tmp_path / "a"), str(tmp_path / "b"))
    r = _sniffer("live", "--bus", str(bus), "--only-link", "fans", "--headless", "--no-out", home=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no [[links]] named 'fans'" in r.stderr
    assert "(it has: drives, pumps)" in r.stderr
    r = _sniffer("live", str(tmp_path / "a"), "--only-link", "drives", "--headless", "--no-out", home=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--bus file with [[links]]" in r.stderr


def test_tshark_captures_one_link_of_a_bus_file(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1", name="a") as a, \
            SimulatedLine(tmp_path, "default", "9600 8E1", name="b", seed=9) as b:
        bus = _two_link_bus(tmp_path, a.path, b.path)
        _install(tmp_path, "--list-bus", str(bus))
        value = f"rs485-link:{bus}#pumps"
        listed = subprocess.run(["tshark", "-D"], capture_output=True, text=True, timeout=120, env=_env(tmp_path))
        assert value in listed.stdout and "plant.toml: pumps" in listed.stdout
        r, out = _tshark_capture(tmp_path, value, 6)
        written = a.pty.bytes_received_from_sniffer + b.pty.bytes_received_from_sniffer
    assert r.returncode == 0 and "Error" not in r.stderr, r.stderr
    assert written == 0
    assert not _left_running(str(tmp_path))
    names = subprocess.run(["tshark", "-r", out, "-T", "fields", "-e", "frame.interface_name"], capture_output=True,
                           text=True, timeout=120).stdout.split("\n")
    assert {n for n in names if n} and all(n.startswith("pumps") for n in names if n)  # that link only
    packets = _packets(out)
    assert len(packets) > 20 and sum("mbrtu" in p[0] for p in packets) >= 0.9 * len(packets)
    assert all("[pumps]" in p[2] for p in packets if "mbrtu" in p[0])  # each frame's comment names its link
