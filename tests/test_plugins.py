"""Plugins (sniffer/plugins/, docs/plugins.md): the example package in docs/examples/acme-plugin is built,
installed into a fresh virtual environment, listed by `sniffer models`, and captures a simulated ACME Link line
on a pty; plugins that fail to import or have a wrong interface are one warning line each, and the rest works."""

from __future__ import annotations

import json
import os
import random
import shutil
import subprocess
import sys
import sysconfig
import threading
import time
import tty
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "examples" / "acme-plugin"
sys.path.insert(0, str(EXAMPLE))  # the example's own modules, for the framer tests in this process

from acme_plugin.framing import frame  # noqa: E402
from helpers import fr  # noqa: E402

BROKEN = {  # distribution -> (entry point group, its entries, module source)
    "broken-import": ("rs485_sniffer.models", "gone = broken_import_mod:MODEL", "import no_such_module_here\n"),
    "wrong-shape": ("rs485_sniffer.protocols", "shapeless = wrong_shape_mod:PROTOCOL",
                    "class PROTOCOL:\n    name = 'shapeless'\n    framer = None\n    decoder = None\n"),
}


def _run(python: Path, *args, timeout=120) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run([str(python), *map(str, args)], capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=python.parent)


@pytest.fixture(scope="module")
def venv(tmp_path_factory) -> Path:
    """A fresh virtual environment that sees this checkout's packages (a .pth, so nothing is installed twice)
    and has the example plugin installed from the wheel built of its folder: its python."""
    work = tmp_path_factory.mktemp("plugin")
    src = work / "acme-plugin"
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "build"))
    dist = work / "dist"
    for isolation in (["--no-build-isolation"], []):  # offline where this setuptools can build a wheel
        r = _run(Path(sys.executable), "-m", "pip", "wheel", "-q", "--no-deps", *isolation, "-w", dist, src,
                 timeout=600)
        if r.returncode == 0:
            break
    assert r.returncode == 0, r.stderr[-2000:]
    (wheel,) = dist.glob("acme_sniffer_plugin-*.whl")
    root = work / "venv"
    assert _run(Path(sys.executable), "-m", "venv", "--without-pip", root).returncode == 0
    python = root / "bin" / "python"
    site = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    (site / "_checkout.pth").write_text(f"import site; site.addsitedir({sysconfig.get_paths()['purelib']!r})\n")
    r = _run(python, "-m", "pip", "install", "-q", "--no-index", "--no-deps", wheel, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (site / "acme_plugin" / "acme-x2.toml").is_file()
    return python


def _install_broken(python: Path) -> Path:
    """Two more installed distributions: one whose module does not import, one of the wrong shape."""
    site = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    for name, (group, entry, source) in BROKEN.items():
        info = site / f"{name.replace('-', '_')}-1.0.dist-info"
        info.mkdir(exist_ok=True)
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
        (info / "entry_points.txt").write_text(f"[{group}]\n{entry}\n")
        (site / f"{name.replace('-', '_')}_mod.py").write_text(source)
    return site


def test_models_lists_the_plugins_and_where_they_come_from(venv):
    r = _run(venv, "-m", "sniffer", "models", "--format", "json")
    assert r.returncode == 0 and not r.stderr, r.stderr
    got = json.loads(r.stdout)
    models = {m["model"]: m for m in got["models"]}
    protocols = {p["protocol"]: p for p in got["protocols"]}
    assert models["a510"]["from"] == "built in" and protocols["modbus-rtu"]["from"] == "built in"
    for row in (models["acme-x2"], models["acme-vfd"], protocols["acme-link"]):
        assert row["package"] == "acme-sniffer-plugin 0.1.0" and str(venv.parents[1]) in row["location"], row
    assert models["acme-x2"]["map"].endswith("acme_plugin/acme-x2.toml")
    assert protocols["acme-link"]["default_model"] == "acme-vfd" and got["left_out"] == []
    text = _run(venv, "-m", "sniffer", "models").stdout
    assert "acme-link" in text and "plugin acme-sniffer-plugin 0.1.0" in text
    # --protocol takes it; the model map decodes Modbus as any --model-file would
    r = _run(venv, "-m", "sniffer", "decode", "--device", "5=acme-x2", fr("050301000002"), fr("0503040190012C"))
    assert r.returncode == 0 and "Pump speed=40" in r.stdout and "Discharge pressure=3" in r.stdout, r.stdout + r.stderr


class AcmeLine:
    """A simulated ACME Link line on a pty: a master reads unit 3's four registers, the drive answers (every
    fifth answer with a bad CRC, one error reply to a write).  What the sniffer writes to its end would come
    out on this side: `echoed` keeps it."""

    def __init__(self) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self.slave = slave
        self.stop = threading.Event()
        self.sent: list[bytes] = []
        self.thread = threading.Thread(target=self.play, daemon=True)

    def play(self) -> None:
        n = 0
        while not self.stop.is_set():
            v = 500 + n
            frames = [frame(0x7E, 3, 1, bytes([0, 0, 4])),
                      frame(0x7F, 3, 1, bytes([0, 0, 4]) + b"".join(x.to_bytes(2, "big") for x in (v, v - 4, 123, 0)))]
            if n % 5 == 4:
                frames[1] = frames[1][:-1] + bytes([frames[1][-1] ^ 0xFF])
            if n % 7 == 6:
                frames = [frame(0x7E, 3, 2, bytes([0, 0, 1, 0xF4])), frame(0x7F, 3, 0x82, bytes([3]))]
            for raw in frames:
                os.write(self.master, raw)
                self.sent.append(raw)
                time.sleep(0.02)
            n += 1
            time.sleep(0.06)

    def echoed(self) -> bytes:
        os.set_blocking(self.master, False)
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""


def test_the_example_plugin_captures_a_simulated_line(venv, tmp_path):
    line = AcmeLine()
    line.thread.start()
    out = tmp_path / "acme.mcap"
    try:
        r = _run(venv, "-m", "sniffer", "live", line.path, "--baud", "19200", "--protocol", "acme-link", "--headless",
                 "--format", "jsonl", "--duration", "2.5", "--out", out, timeout=120)
    finally:
        line.stop.set()
        line.thread.join(5)
    assert r.returncode == 0, r.stderr
    assert line.echoed() == b"", "the sniffer wrote to the line"
    recs = [json.loads(x) for x in r.stdout.splitlines()]
    frames = [x for x in recs if x["protocol"] == "acme-link"]
    assert len(frames) > 10 and all(x["model"] == "acme-vfd" for x in frames)
    sent = {raw.hex() for raw in line.sent}
    # every frame is one the line sent, whole; but the capture starts and ends where it does, perhaps inside one
    inner = [x for x in frames if x["index"] not in (recs[0]["index"], recs[-1]["index"])]
    assert {x["raw"] for x in inner} <= sent
    answers = [x for x in inner if x["role"] == "response" and x["function"] == 1]
    assert answers and all(x["pair"] is not None for x in answers)
    good = [x for x in answers if x["crc_ok"]]
    assert good and all(p["name"] == "Speed setpoint" and p["unit"] == "Hz" for p in (x["points"][0] for x in good))
    bad = [x for x in answers if not x["crc_ok"]]
    assert all(any(a["code"] == "modbus.crc.mismatch" for a in x["annotations"]) for x in bad)
    assert len(good) > len(bad)
    # and the capture replays with the plugin, to the same frames
    rr = _run(venv, "-m", "sniffer", "replay", out, "--format", "jsonl")
    assert rr.returncode == 0, rr.stderr
    again = [json.loads(x) for x in rr.stdout.splitlines()]
    assert [(x["raw"], x["role"], x["summary"]) for x in again if x["protocol"] == "acme-link"] == \
           [(x["raw"], x["role"], x["summary"]) for x in frames]


def test_a_broken_plugin_is_one_warning_line_and_the_rest_works(venv):
    site = _install_broken(venv)
    try:
        r = _run(venv, "-m", "sniffer", "models")
        assert r.returncode == 0, r.stderr
        warnings = r.stderr.splitlines()
        assert len(warnings) == 2, r.stderr
        assert any("plugin gone (rs485_sniffer.models" in w and "from broken-import 1.0" in w
                   and "No module named 'no_such_module_here'" in w for w in warnings), r.stderr
        assert any("plugin shapeless (rs485_sniffer.protocols" in w and "wrong interface: framer must be" in w
                   for w in warnings), r.stderr
        assert "acme-link" in r.stdout and "left out" in r.stdout and "Traceback" not in r.stderr
        hexes = [frame(0x7E, 3, 1, bytes([0, 0, 1])).hex(), frame(0x7F, 3, 1, bytes([0, 0, 1, 1, 0xF4])).hex()]
        r = _run(venv, "-m", "sniffer", "decode", "--protocol", "acme-link", *hexes)
        assert r.returncode == 0 and "Speed setpoint=50.0 Hz" in r.stdout, r.stdout + r.stderr
        # each broken plugin said once, however many times the tables are asked for in the run
        assert r.stderr.count("plugin gone ") == 1 and r.stderr.count("plugin shapeless ") == 1, r.stderr
    finally:
        for name in BROKEN:
            shutil.rmtree(site / f"{name.replace('-', '_')}-1.0.dist-info")
            (site / f"{name.replace('-', '_')}_mod.py").unlink()


# ---- the framer of a plugin, in this process: PacketFramer's rules over the example's ACME Link ----------------

def _frames(chunks):
    from acme_plugin.framing import AcmeFramer

    from sniffer.events import Chunk
    from sniffer.line import LineSettings

    fr = AcmeFramer(LineSettings(19200, "N", 1, 8))
    out = []
    for t, data in chunks:
        out += fr.feed(Chunk(t, data))
    return out + fr.flush()


def test_packet_framer_conserves_bytes_and_ignores_chunking():
    rng = random.Random(3)
    wire = b"".join([frame(0x7E, 3, 1, bytes([0, 0, 2])), b"\x00\x55", frame(0x7F, 3, 1, bytes([0, 0, 2, 1, 2, 3, 4])),
                     frame(0x7F, 9, 0x81, bytes([1]))[:-1] + b"\x00", frame(0x7E, 4, 2, bytes([0, 1, 0, 9]))[:5]])
    whole = _frames([(10_000_000, wire)])
    assert b"".join(f.raw for f in whole) == wire  # every byte in exactly one frame
    kinds = [(f.protocol, f.crc_ok, f.unit) for f in whole]
    assert kinds == [("acme-link", True, 3), ("noise", None, None), ("acme-link", True, 3), ("acme-link", False, 9),
                     ("acme-link", False, 4)]
    assert [a.code for a in whole[4].annotations] == ["modbus.length.truncated"]
    pieces, i, t = [], 0, 10_000_000
    while i < len(wire):  # the same bytes in random reads, back to back
        n = rng.randint(1, 7)
        pieces.append((t, wire[i:i + n]))
        i, t = i + n, t + 1_000
    assert [(f.raw, f.crc_ok) for f in _frames(pieces)] == [(f.raw, f.crc_ok) for f in whole]


def test_a_plugin_of_the_wrong_shape_is_refused_with_why():
    from sniffer.plugins.models import check as check_model
    from sniffer.plugins.protocols import check as check_protocol

    class NoDecode:
        model, codes = "x1", ()

    with pytest.raises(TypeError, match="no decode"):
        check_model("x1", NoDecode())
    with pytest.raises(ValueError, match="model must be an id"):
        check_model("x1", type("Bad", (), {"model": "Has Spaces", "codes": (), "decode": lambda *a: None})())
    with pytest.raises(ValueError, match="is not a file"):
        check_model("x1", Path("/no/such/map.toml"))
    import acme_plugin

    ok = check_protocol("acme-link", acme_plugin.PROTOCOL)
    assert ok.decoder.model == "acme-vfd" and ok.framer.protocol == "acme-link"
    with pytest.raises(ValueError, match="built-in protocol"):
        check_protocol("modbus-rtu", type("P", (), {"name": "modbus-rtu"})())


def test_packet_framer_never_raises_and_keeps_every_byte():
    from hypothesis import given, settings
    from hypothesis import strategies as st

    good = frame(0x7F, 3, 1, bytes([0, 0, 1, 1, 0xF4]))

    @settings(max_examples=100, deadline=None)
    @given(st.lists(st.one_of(st.binary(max_size=12), st.just(good), st.just(good[:-3])), max_size=12),
           st.lists(st.integers(1, 9), min_size=1, max_size=20))
    def check(parts, cuts):
        wire = b"".join(parts)
        pieces, i, t, k = [], 0, 10_000_000, 0
        while i < len(wire):
            n = cuts[k % len(cuts)]
            pieces.append((t, wire[i:i + n]))
            i, t, k = i + n, t + 1_000, k + 1
        got = _frames(pieces)
        assert b"".join(f.raw for f in got) == wire
        assert all(f.raw for f in got) and all(0 <= a.start < a.end <= len(f.raw) for f in got for a in f.annotations)

    check()
