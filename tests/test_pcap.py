"""pcap export (Wireshark's Modbus/RTU dissector decodes it) and pcap/pcapng import."""

from __future__ import annotations

import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from helpers import decoded
from helpers import export as _export

from sniffer.framing.crc import crc_bytes
from sniffer.formats.pcap.format import TSHARK_ARGS, global_header, packet
from sniffer.capture.session import CaptureSpec
from sniffer.events import CaptureError
from sniffer.formats.pcap.reader import open_pcap, read_packets, sniff

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
WIZ = CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"
ERRORS = CAPTURES / "sim" / "errors.mcap"
BAUD = CaptureSpec.of(baud=9600)


def export(capture, fmt, out, spec=None) -> int:
    flags = ["--baud", str(spec.flags.baud)] if spec is not None else []
    return _export(capture, fmt, out, *flags)


def decode_capture(path, spec=None):
    return decoded(path, spec)


def _fields(frames):
    return [(f.unit, f.function, f.role, f.raw) for f in frames]


@pytest.mark.skipif(shutil.which("tshark") is None,
                    reason="tshark not installed (scripts/install-system-deps.sh installs it)")
@pytest.mark.parametrize("ext", ["pcap", "pcapng"])
def test_tshark_decodes_our_pcap_as_modbus_rtu(tmp_path, ext):
    out = tmp_path / f"wiz.{ext}"
    export(WIZ, "pcap", out, BAUD)
    _info, frames = decode_capture(WIZ, BAUD)
    r = subprocess.run(
        ["tshark", "-r", str(out), *TSHARK_ARGS, "-T", "fields",
         "-e", "frame.protocols", "-e", "mbrtu.unit_id", "-e", "modbus.func_code"],
        capture_output=True, text=True, timeout=120, check=True)
    rows = [line.split("\t") for line in r.stdout.splitlines()]
    assert len(rows) == len(frames) == 88
    for f, (protocols, unit, fc) in zip(frames, rows):
        assert "mbrtu" in protocols and "modbus" in protocols
        assert int(unit) == f.unit
        assert int(fc) == f.function, (f, fc)


@pytest.mark.skipif(shutil.which("tshark") is None,
                    reason="tshark not installed (scripts/install-system-deps.sh installs it)")
def test_tshark_reads_noise_and_bad_crc_frames_too(tmp_path):
    out = tmp_path / "errors.pcap"
    assert export(ERRORS, "pcap", out) == 0
    n = len(decode_capture(ERRORS)[1])
    r = subprocess.run(["tshark", "-r", str(out), *TSHARK_ARGS, "-T", "fields", "-e", "frame.number"],
                       capture_output=True, text=True, timeout=120, check=True)
    assert len(r.stdout.split()) == n == 432


@pytest.mark.parametrize("ext", ["pcap", "pcapng"])
def test_pcap_roundtrip_gives_the_same_frames(tmp_path, ext):
    out = tmp_path / f"wiz.{ext}"
    export(WIZ, "pcap", out, BAUD)
    assert sniff(out)
    assert _fields(decode_capture(out, BAUD)[1]) == _fields(decode_capture(WIZ, BAUD)[1])


def _frames():
    req = bytes.fromhex("010300000002")
    rsp = bytes.fromhex("01030400010002")
    return [req + crc_bytes(req), rsp + crc_bytes(rsp)] * 3


def _pcapng(path: Path, linktype: int, payloads, tsresol: int | None = 9, header: bytes = b"") -> Path:
    def block(btype: int, body: bytes) -> bytes:
        body += b"\0" * (-len(body) % 4)
        return struct.pack("<II", btype, len(body) + 12) + body + struct.pack("<I", len(body) + 12)

    shb = block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
    opts = b"" if tsresol is None else struct.pack("<HHB3x", 9, 1, tsresol) + struct.pack("<HH", 0, 0)
    idb = block(1, struct.pack("<HHI", linktype, 0, 65535) + opts)
    unit = 1 if tsresol == 9 else 1000
    epbs = b""
    for i, p in enumerate(payloads):
        ts = (1_700_000_000_000_000_000 + i * 50_000_000) // unit
        data = header + p
        epbs += block(6, struct.pack("<IIIII", 0, ts >> 32, ts & 0xFFFFFFFF, len(data), len(data)) + data)
    path.write_bytes(shb + idb + epbs)
    return path


def test_pcapng_user_dlt_import(tmp_path):
    p = _pcapng(tmp_path / "a.pcapng", 147, _frames())
    assert sniff(p)
    info, frames = decode_capture(p, BAUD)
    assert info.time_source == "read" and info.wall_anchor_ns == 1_700_000_000_000_000_000
    assert [(f.role, f.function) for f in frames] == [("request", 3), ("response", 3)] * 3
    assert frames[1].latency_ms is not None and frames[1].points[0]["value"] == 1
    # 50 ms apart in the file: times come through in ns
    assert frames[2].t_ns - frames[0].t_ns == 100_000_000


def test_pcapng_microsecond_default_resolution(tmp_path):
    p = _pcapng(tmp_path / "us.pcapng", 147, _frames(), tsresol=None)
    pk = read_packets(p)
    assert pk[1][1] - pk[0][1] == 50_000_000


def test_rtac_serial_250_import_strips_its_header(tmp_path):
    header = struct.pack(">IIBBH", 1_700_000_000, 0, 0x02, 0, 0)  # 12-byte RTAC serial header
    p = _pcapng(tmp_path / "rtac.pcapng", 250, _frames(), header=header)
    assert [d for _lt, _t, d in read_packets(p)] == _frames()
    _info, frames = decode_capture(p, BAUD)
    assert all(f.crc_ok for f in frames) and len(frames) == 6


def test_classic_pcap_microseconds_big_endian(tmp_path):
    p = tmp_path / "be.pcap"
    data = struct.pack(">IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 147)
    for i, fr in enumerate(_frames()):
        data += struct.pack(">IIII", 1_700_000_000, i * 50_000, len(fr), len(fr)) + fr
    p.write_bytes(data)
    assert [d for _lt, _t, d in read_packets(p)] == _frames()
    assert read_packets(p)[1][1] - read_packets(p)[0][1] == 50_000_000


def test_truncated_pcap_keeps_complete_packets(tmp_path):
    p = tmp_path / "cut.pcap"
    data = global_header() + b"".join(packet(10**18 + i * 10**7, f) for i, f in enumerate(_frames()))
    p.write_bytes(data[:-3])
    assert len(read_packets(p)) == 5


def test_other_link_types_are_a_clear_error(tmp_path):
    p = tmp_path / "eth.pcap"
    p.write_bytes(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1) + packet(0, b"x" * 60)[:16] + b"x" * 60)
    with pytest.raises(CaptureError, match="link type 1 is not a serial capture"):
        open_pcap(p)
    q = tmp_path / "not.pcap"
    q.write_bytes(b"hello world")
    assert not sniff(q)
