"""The pcapng stream's packet comments (formats/pcap/comments.py), read back from the bytes the sink wrote: what
Wireshark shows under each packet.  tshark reading them live is tests/test_extcap.py."""

from __future__ import annotations

import io
import struct

from decoders.registry import default_registry
from sniffer.capture.pipeline import Pipeline
from sniffer.events import CaptureInfo
from sniffer.formats.pcap.writer import PcapSink
from sniffer.simulator import get_scenario, simulate, usb_chunks, wire_chunks


class _Keep(io.BytesIO):
    def close(self) -> None:  # the sink closes its file; the test still reads it
        pass


def _packets(scenario: str, adapter: str) -> list[tuple[bytes, str]]:
    sc = get_scenario(scenario)
    sent = list(simulate(sc, sc.line, 3.0, 3))
    chunks = wire_chunks(sent) if adapter == "wire" else usb_chunks(sent, seed=3)
    out = _Keep()
    info = CaptureInfo(baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits,
                       time_source="byte" if adapter == "wire" else "read")
    p = Pipeline(info, sc.line, default_registry(sc.devices), [PcapSink(out, ng=True, comments=True)],
                 protocol=sc.protocol)
    for c in chunks:
        p.feed(c)
    p.finish()
    return _blocks(out.getvalue())


def _blocks(data: bytes) -> list[tuple[bytes, str]]:
    """(packet bytes, opt_comment) of every enhanced packet block."""
    found, pos = [], 0
    while pos < len(data):
        btype, blen = struct.unpack_from("<II", data, pos)
        if btype == 6:
            caplen = struct.unpack_from("<I", data, pos + 20)[0]
            raw = data[pos + 28:pos + 28 + caplen]
            opt = pos + 28 + caplen + (-caplen % 4)
            comment = ""
            while opt < pos + blen - 4:
                code, olen = struct.unpack_from("<HH", data, opt)
                if code == 0:
                    break
                if code == 1:
                    comment = data[opt + 4:opt + 4 + olen].decode()
                opt += 4 + olen + (-olen % 4)
            found.append((raw, comment))
        pos += blen
    return found


def test_every_packet_says_what_only_we_know():
    packets = _packets("default", "usb")
    assert len(packets) > 50 and all(c.startswith("rs485-sniffer #") for _, c in packets)
    assert sum("answers #" in c for _, c in packets) > 10
    assert any("latency" in c and " ms" in c for _, c in packets)
    assert any(" = " in c for _, c in packets)  # a register by name, with its value
    assert all(c.splitlines()[-1] == "time per read: estimated from the read and the baud rate" for _, c in packets)


def test_bad_bytes_are_said():
    packets = _packets("errors", "wire")
    bad = [(raw, c) for raw, c in packets if "CRC BAD" in c]
    assert bad and all("modbus.crc" in c for _, c in bad)
    assert any(": noise," in c.splitlines()[0] for _, c in packets)
    assert all(c.splitlines()[-1] == "time per byte: measured" for _, c in packets)
