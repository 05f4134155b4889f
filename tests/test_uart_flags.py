"""A byte the UART flagged (framing or parity error) never ends up inside a CRC-valid frame.

CRC-16/MODBUS checks any valid frame followed by a 0x00 one byte longer too (the old CRC's
low byte becomes data, its high byte and the 0x00 the new CRC).  A line driver that leaves a
0x00 with a framing error at turn-off, right after each request, then makes a request whose
third byte is 04 read as a 9-byte response.  The fixtures in captures/uart (written by
captures/uart/generate.py) hold that line; the same bytes without their flags (an adapter that
reports no UART errors) must frame the same, on what is pending and the roles the bytes can have.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from helpers import run_events

from sniffer.framing.crc import crc_bytes, crc_ok
from sniffer.events import Chunk
from sniffer.frame import REQUEST, RESPONSE
from sniffer.line import LineSettings
from sniffer.formats.bytecsv.reader import open_byte_csv

UART = Path(__file__).resolve().parent.parent / "captures" / "uart"
RTU_LINE = LineSettings(9600, "N", 1)
ASCII_LINE = LineSettings(9600, "E", 1, 7)


def chunks(name: str, keep_flags: bool = True) -> list[Chunk]:
    _info, events = open_byte_csv(UART / name)
    out = list(events)
    if not keep_flags:
        out = [Chunk(c.t_ns, c.data, c.byte_t_ns, (), c.channel) for c in out]
    return out


def flagged_offsets(events: list[Chunk]) -> set[int]:
    """Offsets of the flagged bytes in the whole stream (one channel: frames follow byte order)."""
    out, n = set(), 0
    for c in events:
        out |= {n + k for k, _flag in c.flags}
        n += len(c.data)
    return out


def good_frames_holding_a_flag(frames, flagged: set[int]) -> list:
    bad, n = [], 0
    for f in frames:
        if f.crc_ok and any(n <= k < n + len(f.raw) for k in flagged):
            bad.append(f)
        n += len(f.raw)
    return bad


def byte_by_byte(events: list[Chunk]) -> list[Chunk]:
    out = []
    for c in events:
        flags = dict(c.flags)
        for k, b in enumerate(c.data):
            flag = ((0, flags[k]),) if k in flags else ()
            out.append(Chunk(c.byte_t_ns[k] + RTU_LINE.char_ns, bytes([b]), (c.byte_t_ns[k],), flag, c.channel))
    return out


def shape(frames) -> list[tuple]:
    return [(f.raw, f.protocol, f.role, f.crc_ok) for f in frames]


@pytest.mark.parametrize("how", ["whole", "byte by byte"])
def test_the_turn_off_zero_never_extends_a_request(how):
    events = chunks("turnoff-rtu.bytes.csv")
    assert len(flagged_offsets(events)) == 7  # every request but the last leaves its 0x00
    got = run_events(events if how == "whole" else byte_by_byte(events), RTU_LINE)
    assert good_frames_holding_a_flag(got, flagged_offsets(events)) == []
    zeros = [f for f in got if f.is_noise]
    assert [f.raw for f in zeros] == [b"\x00"] * 7
    assert all(f.annotations[0].code in ("uart.framing_error", "uart.parity_error") for f in zeros)
    frames = [f for f in got if not f.is_noise]
    assert all(f.crc_ok for f in frames)
    requests = [f for f in frames if f.role == REQUEST]
    assert all(len(f.raw) == 8 for f in requests) and len(requests) == 8
    # every response answers its request; the only unanswered request is the one retried
    assert all(f.pair is not None for f in frames if f.role == RESPONSE)
    assert sum(f.pair is None for f in requests) == 1
    # the response whose first 8 bytes check as a request is kept whole: a request it answers is pending
    assert bytes.fromhex("01030444ea370a5900") in [f.raw for f in frames if f.role == RESPONSE]


def test_without_flags_what_is_pending_decides_the_same():
    """An adapter that reports no UART errors: the same frames, from what is pending and the roles."""
    with_flags = run_events(chunks("turnoff-rtu.bytes.csv"), RTU_LINE)
    without = run_events(chunks("turnoff-rtu.bytes.csv", keep_flags=False), RTU_LINE)
    assert shape(without) == shape(with_flags)


def test_per_read_turn_off_zero_with_nothing_pending():
    """A USB adapter's reads: the request and its 0x00 in one read, the answer in the next."""
    def rtu(h):
        return bytes.fromhex(h) + crc_bytes(bytes.fromhex(h))

    req, rsp = rtu("010304060001"), rtu("01030204d2")
    assert crc_ok(req + b"\x00")  # the trap: request + 0x00 is a CRC-valid 9-byte response
    events, t = [], 10_000_000
    for _ in range(3):
        events += [Chunk(t, req + b"\x00"), Chunk(t + 15_000_000, rsp)]
        t += 200_000_000
    got = run_events(events, RTU_LINE)
    assert [(f.raw, f.role) for f in got] == [(req, REQUEST), (b"\x00", "noise"), (rsp, RESPONSE)] * 3


def test_a_retry_of_a_two_register_read_is_not_taken_for_its_answer():
    """The unanswered request is pending, and request + 0x00 would even have the answer's size:
    the 8 bytes repeat the pending request byte for byte, so they are the retry."""
    def rtu(h):
        return bytes.fromhex(h) + crc_bytes(bytes.fromhex(h))

    req, rsp = rtu("010304200002"), rtu("01030400050006")
    events = [Chunk(10_000_000, req + b"\x00"), Chunk(200_000_000, req + b"\x00"), Chunk(215_000_000, rsp)]
    got = run_events(events, RTU_LINE)
    assert [(f.raw, f.role) for f in got] == [(req, REQUEST), (b"\x00", "noise"), (req, REQUEST),
                                              (b"\x00", "noise"), (rsp, RESPONSE)]


def test_pd_rtu_a_long_len_does_not_take_the_flagged_zero():
    """PD-series: a LEN one too long points at the turn-off 0x00, and the CRC holds over it."""
    events = chunks("turnoff-pd.bytes.csv")
    got = run_events(events, RTU_LINE, protocol="pd-rtu")
    assert good_frames_holding_a_flag(got, flagged_offsets(events)) == []
    assert [f.raw for f in got if f.is_noise] == [b"\x00"] * 3
    frames = [f for f in got if not f.is_noise]
    assert all(f.crc_ok for f in frames) and all(f.pair is not None for f in frames)
    assert sum(any(a.code == "pd.len.mismatch" for a in f.annotations) for f in frames) == 2


def test_ascii_a_flagged_character_makes_no_lrc_valid_line():
    events = chunks("flagged-ascii.bytes.csv")
    got = run_events(events, ASCII_LINE, protocol="modbus-ascii")
    assert good_frames_holding_a_flag(got, flagged_offsets(events)) == []
    frames = [f for f in got if not f.is_noise]
    bad = [f for f in frames if not f.crc_ok]
    assert len(frames) == 6 and len(bad) == 1
    codes = [a.code for a in bad[0].annotations]
    assert "uart.parity_error" in codes and "modbus.crc.unproven" in codes
    assert bad[0].crc_expected is None  # the LRC matched: there is no other value to expect
    assert [f.raw for f in got if f.is_noise] == [b"\x00"]


def test_a_flag_inside_a_frame_makes_it_damaged_not_noise():
    """The frame keeps its header and roles; its CRC verdict is unproven."""
    def rtu(h):
        return bytes.fromhex(h) + crc_bytes(bytes.fromhex(h))

    req = rtu("010300100002")
    times = tuple(i * RTU_LINE.char_ns for i in range(8))
    got = run_events([Chunk(times[-1], req, times, ((3, "parity"),))], RTU_LINE)
    assert [(f.raw, f.unit, f.function, f.crc_ok) for f in got] == [(req, 1, 3, False)]
    assert [a.code for a in got[0].annotations][:2] == ["uart.parity_error", "modbus.crc.unproven"]


def test_random_flags_never_sit_inside_a_good_frame():
    """Property: on simulated traffic with flags put on random bytes, no CRC-valid frame holds one."""
    from sniffer.simulator import get_scenario, simulate, wire_chunks

    sc = get_scenario("default")
    rnd = random.Random(7)
    events = []
    for c in wire_chunks(simulate(sc, sc.line, 3, 11)):
        flags = dict(c.flags)
        for k in range(len(c.data)):
            if rnd.random() < 0.02:
                flags[k] = rnd.choice(("framing", "parity"))
        events.append(Chunk(c.t_ns, c.data, c.byte_t_ns, tuple(sorted(flags.items())), c.channel))
    got = run_events(events, sc.line, devices=sc.devices)
    assert sum(len(f.raw) for f in got) == sum(len(c.data) for c in events)
    assert good_frames_holding_a_flag(got, flagged_offsets(events)) == []
    assert sum(f.crc_ok is True for f in got) > 20
