"""The same bytes in any input format give the same frames.

Each stream is a list of bursts (what the wire carried back to back); it is written as a byte CSV,
a Saleae Logic 2 export, a pcap and a pcapng (one packet per burst: a boundary the capturing tool
drew), and an MCAP (per-byte reads, and the pcap's reads recorded again), and every file is decoded
through the session as a user's replay is.  The frames (bytes, protocol, unit, function, role, CRC
verdict, framing annotations) must agree; timing verdicts may differ (a pcap packet has one time).
"""

from __future__ import annotations

import pytest
from helpers import decoded

from sniffer.framing.crc import crc_bytes
from sniffer.events import CaptureInfo, Chunk
from sniffer.line import LineSettings
from sniffer.formats.pcap.format import global_header, packet, pcapng_header, pcapng_packet
from sniffer.capture.session import CaptureSpec
from sniffer.formats.mcap.sink import McapSink
from sniffer.formats.bytecsv.reader import write_byte_csv
from sniffer.formats.pcap.reader import open_pcap

LINE = LineSettings(9600, "N", 1)
SPEC = CaptureSpec.of(baud=9600)
TIMING = ("modbus.timing.", "pair.")  # what depends on per-byte times, not on the bytes


def rtu(h: str) -> bytes:
    b = bytes.fromhex(h)
    return b + crc_bytes(b)


BIG = bytes([1, 4, 164]) + bytes(range(164))

# (ms of silence before, bytes, {offset: flag})
STREAMS = {
    "polls": [
        (0, rtu("010300000002"), {}), (3.5, rtu("01030400010002"), {}),
        (80, rtu("020600100001"), {}), (3.5, rtu("020600100001"), {}),
        (80, rtu("030300000001"), {}), (3.5, rtu("038302"), {}),  # exception 02
        (80, rtu("011000100002040001000a"), {}), (3.5, rtu("011000100002"), {}),
        (80, rtu("010300000002"), {}), (3.5, rtu("01030400010002")[:-1] + b"\x55", {}),  # bad CRC
        (80, bytes.fromhex("ff00ff00ff"), {}),  # line noise
    ],
    "cut-off response": [  # a logger's 96-byte packet limit cut a 169-byte FC04 response
        (0, rtu("010400000052"), {}), (20, rtu(BIG.hex())[:96], {}),
        (200, rtu("010400000052"), {}), (20, rtu(BIG.hex()), {}),
        (200, rtu("010300000001"), {}), (4, rtu("010302002a"), {}),
    ],
    "turn-off zero": [  # the 0x00 a line driver leaves at turn-off: request + 0x00 checks as 9 bytes
        (0, rtu("010300000001") + b"\x00", {8: "framing"}), (3, rtu("010302002a"), {}),
        (100, rtu("010304060001") + b"\x00", {8: "framing"}), (3, rtu("01030204d2"), {}),
        (100, rtu("010404000002") + b"\x00", {8: "parity"}), (3, rtu("01040400010002"), {}),
    ],
}


def chunks(stream) -> list[Chunk]:
    """One per-byte-timed Chunk per burst."""
    out, t = [], 10_000_000
    for gap_ms, data, flags in stream:
        t += round(gap_ms * 1e6)
        times = tuple(t + k * LINE.char_ns for k in range(len(data)))
        out.append(Chunk(times[-1] + LINE.char_ns, data, times, tuple(sorted(flags.items()))))
        t = times[-1] + LINE.char_ns
    return out


def write(fmt: str, stream, path):
    cs = chunks(stream)
    if fmt == "byte-csv":
        write_byte_csv(str(path), cs)
    elif fmt == "saleae":
        with open(path, "w") as fh:
            fh.write("name,type,start_time,duration,data,error\n")
            for c in cs:
                flags = dict(c.flags)
                for k, b in enumerate(c.data):
                    fh.write(f'"Async Serial","data",{c.byte_t_ns[k] / 1e9:.9f},0.00094,0x{b:02X},'
                             f'{flags.get(k, "")}\n')
    elif fmt in ("pcap", "pcapng"):  # one packet per burst, stamped when its last byte ended
        t0 = 1_700_000_000_000_000_000
        with open(path, "wb") as fh:
            fh.write(pcapng_header(CaptureInfo()) if fmt == "pcapng" else global_header())
            for c in cs:
                fh.write((pcapng_packet if fmt == "pcapng" else packet)(t0 + c.t_ns, c.data))
    elif fmt == "mcap":
        sink = McapSink(path)
        sink.start(CaptureInfo(baud=9600, parity="N", stopbits=1))
        for c in cs:
            sink.raw(c)
        sink.close()
    elif fmt == "pcap-recorded-as-mcap":  # the pcap's reads written to an MCAP and read back
        write("pcap", stream, path.with_suffix(".pcap"))
        info, events = open_pcap(path.with_suffix(".pcap"))
        info.baud = 9600
        sink = McapSink(path)
        sink.start(info)
        for ev in events:
            sink.raw(ev)
        sink.close()
    return path


SUFFIX = {"byte-csv": ".csv", "saleae": ".csv", "pcap": ".pcap", "pcapng": ".pcapng", "mcap": ".mcap",
          "pcap-recorded-as-mcap": ".mcap"}


def shape(frames) -> list[tuple]:
    return [(f.raw.hex(), f.protocol, f.unit, f.function, f.role, f.crc_ok,
             sorted(a.code for a in f.annotations if not a.code.startswith(TIMING)))
            for f in frames]


@pytest.mark.parametrize("name", list(STREAMS))
def test_every_input_format_gives_the_same_frames(tmp_path, name):
    stream = STREAMS[name]
    got = {}
    for fmt, suffix in SUFFIX.items():
        path = write(fmt, stream, tmp_path / f"{fmt}{suffix}")
        got[fmt] = shape(decoded(path, SPEC)[1])
    want = got.pop("byte-csv")
    assert sum(len(bytes.fromhex(f[0])) for f in want) == sum(len(b) for _g, b, _f in stream)
    for fmt, frames in got.items():
        if fmt.startswith("pcap"):  # pcap carries no UART flags: those annotations are the CSV's alone
            want_here = [(*f[:6], [c for c in f[6] if not c.startswith("uart.")]) for f in want]
        else:
            want_here = want
        assert frames == want_here, fmt


def test_a_cut_off_pcap_packet_is_a_truncated_response(tmp_path):
    """The packet's end is the tool's boundary: 96 bytes of a 169-byte FC04 response are that response,
    cut off (unit, function, role, bad CRC, how much is missing), not noise, whatever the times say."""
    for spacing_ms in (300, 20):  # 20: stamped at its start, the next packet comes "before" its end
        path = tmp_path / f"cut{spacing_ms}.pcap"
        req, cut = rtu("010400000052"), rtu(BIG.hex())[:96]
        with open(path, "wb") as fh:
            fh.write(global_header())
            for i, data in enumerate((req, cut, req, rtu(BIG.hex()))):
                fh.write(packet(1_700_000_000_000_000_000 + i * spacing_ms * 1_000_000, data))
        frames = decoded(path, SPEC)[1]
        assert [len(f.raw) for f in frames] == [8, 96, 8, 169]
        f = frames[1]
        assert (f.protocol, f.unit, f.function, f.role, f.crc_ok) == ("modbus-rtu", 1, 4, "response", False)
        (note,) = [a for a in f.annotations if a.code == "modbus.length.truncated"]
        assert "96 of the 169 bytes" in note.detail and "73 missing" in note.detail
        assert frames[1].pair == frames[0].index
