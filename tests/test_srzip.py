"""The sigrok session file format (.sr), the logic flags, and the driver-enable fields through MCAP and JSON."""

from __future__ import annotations

import random
import zipfile

import pytest
from srgen import write_sr

from sniffer.events import Chunk, read_fields
from sniffer.frame import Frame
from sniffer.line import SettingsError
from sniffer.formats.mcap.format import decode_event, encode_event
from sniffer.formats.records import frame_json, frame_record, frame_from_record, loads
from sniffer.events import CaptureError
from sniffer.sources.logic_options import DeviceSpec, LogicSpec
from sniffer.sources.files import FileSource
from sniffer.sources.srzip import logic_blocks, parse_rate, rate_text, read_meta, sniff


@pytest.mark.parametrize("text, hz", [("1 MHz", 1_000_000), ("4MHz", 4_000_000), ("1M", 1_000_000),
                                      ("500k", 500_000), ("24000000", 24_000_000), ("1.5 MHz", 1_500_000),
                                      ("100 Hz", 100), ("2.25k", 2250)])
def test_sample_rates_as_sigrok_and_people_write_them(text, hz):
    assert parse_rate(text) == hz
    assert parse_rate(rate_text(hz)) == hz


@pytest.mark.parametrize("text", ["", "fast", "1.5", "0", "-1M", "1 THz", "1e6"])
def test_what_is_not_a_sample_rate(text):
    with pytest.raises(ValueError):
        parse_rate(text)


def test_metadata_and_samples_read_back_in_pieces(tmp_path):
    samples = bytes(range(256)) * 40
    path = write_sr(tmp_path / "a.sr", 2_000_000, ["D0", "RX", "DE"], samples, member_size=1000)
    assert sniff(path)
    meta = read_meta(path)
    assert (meta.samplerate, meta.unitsize, meta.samples) == (2_000_000, 1, len(samples))
    assert meta.channels == {"D0": 0, "RX": 1, "DE": 2} and meta.bit("RX") == 1
    assert len(meta.files) == 11  # logic-1-1 ... logic-1-11, read in their numeric order
    assert b"".join(logic_blocks(meta, block=333)) == samples


def test_two_byte_samples_stay_whole(tmp_path):
    samples = bytes(range(200))
    path = write_sr(tmp_path / "w.sr", 1_000_000, [f"D{i}" for i in range(12)], samples, unitsize=2, member_size=77)
    meta = read_meta(path)
    assert meta.unitsize == 2 and meta.samples == 100 and meta.channels["D11"] == 11
    assert all(len(b) % 2 == 0 for b in logic_blocks(meta, block=9))


def test_files_that_are_not_sigrok_sessions(tmp_path):
    (tmp_path / "t.csv").write_text("t_s,channel,byte_hex,flags\n")
    assert not sniff(tmp_path / "t.csv")
    with zipfile.ZipFile(tmp_path / "nometa.sr", "w") as z:
        z.writestr("version", "2")
    with pytest.raises(CaptureError, match="no metadata"):
        read_meta(tmp_path / "nometa.sr")
    with zipfile.ZipFile(tmp_path / "norate.sr", "w") as z:
        z.writestr("version", "2")
        z.writestr("metadata", "[device 1]\nprobe1=D0\nunitsize=1\n")
        z.writestr("logic-1-1", b"\x00" * 10)
    with pytest.raises(CaptureError, match="sample rate"):
        read_meta(tmp_path / "norate.sr")
    with pytest.raises(CaptureError):
        read_meta(tmp_path)


def test_damaged_samples_are_one_line(tmp_path):
    samples = random.Random(1).randbytes(20_000)  # does not compress: the damage lands inside the samples
    path = write_sr(tmp_path / "d.sr", 1_000_000, ["L"], samples, member_size=1 << 20)
    data = bytearray(path.read_bytes())
    i = data.index(b"logic-1-1") + 2000  # inside the compressed samples
    data[i:i + 8] = bytes(8) if data[i:i + 8] != bytes(8) else b"\xff" * 8
    path.write_bytes(bytes(data))
    with pytest.raises(CaptureError, match="cannot be read"):
        b"".join(logic_blocks(read_meta(path)))


def test_logic_flags_are_for_logic_captures(tmp_path):
    csv = tmp_path / "b.csv"
    csv.write_text("t_s,channel,byte_hex,flags\n0.001,RX,01,\n")
    with pytest.raises(CaptureError, match="for a sigrok logic capture"):
        FileSource(csv, logic=LogicSpec("RX", baud=9600)).open()
    with pytest.raises(SettingsError):
        LogicSpec("D0", "D0")
    with pytest.raises(SettingsError):
        DeviceSpec.parse("sigrok:fx2lafw:conn")
    assert DeviceSpec.parse("sigrok:fx2lafw:conn=1.5").arg == "fx2lafw:conn=1.5"


def test_a_de_window_crosses_pipes_and_mcap_unchanged():
    for de in ((1_000, 9_000), (None, 9_000), (1_000, None)):
        c = Chunk(2_000, b"\x01\x03", (2_000, 3_000), (), "TX+DE", de=de)
        assert Chunk(*read_fields(c)) == c
        assert decode_event(encode_event(c)) == c
    plain = Chunk(2_000, b"\x01", (2_000,))
    assert decode_event(encode_event(plain)) == plain and b'"de"' not in encode_event(plain)


def test_de_times_are_in_the_record_only_when_known():
    f = Frame(0, 1_000_000, 2_000_000, b"\x01\x03", "modbus-rtu")
    assert "de_on_ns" not in loads(frame_json(f, 0)) and "de_on_ns" not in frame_record(f, 0)
    f = Frame(1, 1_000_000, 2_000_000, b"\x01\x03", "modbus-rtu")
    f.de_on_ns, f.de_off_ns = -50_000, 30_000
    rec = loads(frame_json(f, 0))
    assert (rec["de_on_ns"], rec["de_off_ns"]) == (-50_000, 30_000) == (frame_record(f, 0)["de_on_ns"],
                                                                         frame_record(f, 0)["de_off_ns"])
    back = frame_from_record(rec)
    assert (back.de_on_ns, back.de_off_ns) == (-50_000, 30_000)
