"""sigrok-cli's UART (and driver-enable) annotations -> Chunks and Ticks, sans-I/O: no sigrok-cli needed.

The lines are what sigrok-cli -l 4 --protocol-decoder-samplenum prints, in the
order it prints them: every DE edge of a block of samples before the UART's
annotations of that block (the counter decoder runs first).
"""

from __future__ import annotations

from helpers import fr, run_events
from sniffer.events import FLAG_FRAMING, FLAG_PARITY, Chunk, Tick
from sniffer.line import LineSettings
from sniffer.capture.pipeline import roles_of
from sniffer.formats.text import frame_line
from sniffer.sources.logic_options import LogicSpec
from sniffer.sources.sigrok_uart import HOLD_BYTES, SigrokUart, decoder_args

RATE, BAUD = 1_000_000, 10_000  # 100 samples a bit: the start-bit annotation begins on the falling edge
LINE = LineSettings(BAUD, "E", 1)
CHAR = 1100  # samples a character (11 bits)


def byte(side: str, start: int, value: int, *, parity_error=False, framing_error=False) -> list[bytes]:
    out = [f'{start}-{start + 100} uart-1: {side}-start: "Start bit" "Start" "S"',
           f'{start + 100}-{start + 900} uart-1: {side}-data: "{value:02X}"']
    out.append(f'{start + 900}-{start + 1000} uart-1: {side}-parity-' + (
        'err: "Parity error" "Parity err" "PE"' if parity_error else 'ok: "Parity bit" "Parity" "P"'))
    if framing_error:
        out.append(f'{start + 1000}-{start + 1100} uart-1: {side}-warnings: "Frame error" "Frame err" "FE"')
    out.append(f'{start + 1000}-{start + 1100} uart-1: {side}-parity-ok: "Stop bit" "Stop" "T"')
    return [x.encode() for x in out]


def burst(side: str, start: int, data: bytes) -> list[bytes]:
    return [line for i, b in enumerate(data) for line in byte(side, start + i * CHAR, b)]


def rise(at: int, n: int = 1) -> bytes:
    return f'0-{at} counter-1: edge_count: "{n}"'.encode()


def fall(at: int) -> bytes:
    return f'{at}-{at} counter-1: word_reset: "Word reset" "Reset" "Rst" "R"'.encode()


def run(lines, logic: LogicSpec, watermarks=(), finish=True) -> list:
    u = SigrokUart(logic, LINE, RATE)
    out = []
    for line in lines:
        if isinstance(line, int):
            u.watermark(line)
        else:
            u.feed(line)
        out += u.take()
    if finish:
        u.finish()
        out += u.take()
    return out


def ns(sample: int) -> int:
    return sample * 1000


def chunks(events) -> list[Chunk]:
    return [e for e in events if type(e) is Chunk]


def test_each_byte_gets_the_sample_time_of_its_start_bit_and_its_uart_errors():
    logic = LogicSpec("RX", baud=BAUD, parity="E")
    lines = byte("rx", 5000, 0x01) + byte("rx", 6100, 0x03, parity_error=True) + byte("rx", 7200, 0, framing_error=True)
    [c] = chunks(run(lines, logic))
    assert c.data == b"\x01\x03\x00" and c.channel == "RX"
    assert c.byte_t_ns == (ns(5000), ns(6100), ns(7200))
    assert c.flags == ((1, FLAG_PARITY), (2, FLAG_FRAMING))


def test_a_frame_error_without_a_start_bit_is_a_glitch_not_a_byte():
    u = SigrokUart(LogicSpec("RX", baud=BAUD), LINE, RATE)
    u.feed(b'400-500 uart-1: rx-warnings: "Frame error" "Frame err" "FE"')
    u.finish()
    assert chunks(u.take()) == [] and u.glitches == 1


def test_rx_and_tx_are_two_wires_with_their_roles():
    logic = LogicSpec("D1", "D0", baud=BAUD, parity="E")
    out = chunks(run(burst("rx", 1000, b"\x01\x06") + burst("tx", 9000, b"\x01\x06"), logic))
    assert [(c.channel, c.data) for c in out] == [("D1", b"\x01\x06"), ("D0", b"\x01\x06")]
    assert logic.roles() == {"D1": "request", "D0": "response"}


def test_bytes_in_a_de_window_wait_for_its_fall_and_carry_both_edges():
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    lines = [rise(19_950), *burst("rx", 1000, b"\x01\x03"), *burst("rx", 20_000, b"\x01\x83\x02")]
    u = SigrokUart(logic, LINE, RATE)
    for line in lines:
        u.feed(line)
    u.watermark(20_000 + 3 * CHAR + 10)  # sigrok's block ended just after the response
    request, = chunks(u.take())  # the response waits: its DE window's fall is not known yet
    assert request.de is None and request.channel == "BUS"
    u.feed(fall(20_000 + 3 * CHAR + 40))  # in the next block
    u.watermark(20_000 + 3 * CHAR + 40 + CHAR)  # the UART read past the fall: no byte of the window is to come
    response, *_ = chunks(u.take())
    assert response.channel == "BUS+DE" and response.data == b"\x01\x83\x02"
    assert response.de == (ns(19_950), ns(20_000 + 3 * CHAR + 40))


def test_a_driver_enabled_after_the_start_bit_still_owns_the_byte():
    """DE rising inside the first character (a late driver): that byte is the window's first."""
    logic = LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E")
    lines = [rise(20_300), *burst("tx", 20_000, b"\x01\x83"), fall(20_000 + 2 * CHAR - 30)]
    [c] = chunks(run(lines, logic))
    assert c.channel == "TX+DE" and c.data == b"\x01\x83"
    assert c.de == (ns(20_300), ns(20_000 + 2 * CHAR - 30))


def test_a_request_byte_inside_the_window_does_not_lose_its_rise():
    """4 wires: the master still sends on RX after the slave's DE rose; its TX answer starts later."""
    logic = LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E")
    out = chunks(run([rise(10_000), *byte("rx", 10_100, 0x0A), *byte("tx", 10_500, 0x01),
                      fall(10_500 + CHAR + 20)], logic))
    assert [(c.channel, c.de) for c in out] == [("RX", None), ("TX+DE", (ns(10_000), ns(10_500 + CHAR + 20)))]


def test_windows_keep_their_own_edges_when_all_edges_come_first():
    """A block of samples holding three transactions: every DE edge is printed before any byte."""
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    edges, data = [], []
    for k in range(3):
        t = 100_000 * k
        edges += [rise(t + 9_900, k + 1), fall(t + 9_900 + 2 * CHAR + 130)]
        data += burst("rx", t, b"\x01\x03") + burst("rx", t + 10_000, b"\x01\x83")
    out = chunks(run(edges + data, logic))
    windows = [c.de for c in out if c.channel == "BUS+DE"]
    assert windows == [(ns(100_000 * k + 9_900), ns(100_000 * k + 9_900 + 2 * CHAR + 130)) for k in range(3)]
    assert [c.channel for c in out] == ["BUS", "BUS+DE"] * 3


def test_a_window_still_open_at_the_end_goes_out_without_its_fall():
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    [c] = chunks(run([rise(900), *burst("rx", 1000, b"\x01\x83")], logic))
    assert c.de == (ns(900), None)


def test_de_stuck_high_does_not_hold_bytes_without_bound():
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    u = SigrokUart(logic, LINE, RATE)
    u.feed(rise(900))
    for line in burst("rx", 1000, bytes(HOLD_BYTES + 10)):
        u.feed(line)
    u.watermark(1000 + (HOLD_BYTES + 10) * CHAR)
    out = chunks(u.take())
    assert sum(len(c.data) for c in out) >= HOLD_BYTES  # released before the end, fall unknown
    assert all(c.de == (ns(900), None) for c in out)


def test_a_watermark_becomes_a_tick_after_the_last_byte():
    logic = LogicSpec("RX", baud=BAUD, parity="E")
    out = run([*burst("rx", 1000, b"\x01\x03"), 50_000], logic, finish=False)
    assert [type(e) for e in out] == [Chunk, Tick]
    assert out[1].t_ns == ns(50_000 - CHAR - 1)  # a character that began before this would have been printed


def test_lines_are_read_up_to_the_watermark_whenever_stdout_was_read():
    """The next block's lines may be read before stderr says the last one is done: they wait for their own."""
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    block1 = [*burst("rx", 1000, b"\x01\x03")]
    block2 = [rise(20_000 - 50), fall(20_000 + 2 * CHAR + 30), *burst("rx", 20_000, b"\x01\x83")]
    early, late = SigrokUart(logic, LINE, RATE), SigrokUart(logic, LINE, RATE)
    out_early, out_late = [], []
    for line in block1 + block2:  # stdout read ahead, then the watermark of block 1
        early.feed(line)
    early.watermark(15_000)
    out_early += early.take()
    for line in block1:
        late.feed(line)
    late.watermark(15_000)
    out_late += late.take()
    request = Chunk(ns(1000), b"\x01\x03", (ns(1000), ns(1000 + CHAR)), channel="BUS")
    assert out_early == out_late == [request, Tick(ns(15_000 - CHAR - 1))]
    for u, out in ((early, out_early), (late, out_late)):
        if u is late:
            for line in block2:
                u.feed(line)
        u.watermark(40_000)
        u.finish()
        out += u.take()
    assert out_early == out_late and out_early[2].de == (ns(19_950), ns(20_000 + 2 * CHAR + 30))


def test_no_tick_jumps_ahead_of_held_bytes():
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    out = run([rise(900), *burst("rx", 1000, b"\x01\x83"), 3000], logic, finish=False)
    assert out == []


def test_roles_and_de_times_reach_the_frames():
    """Through the pipeline: the DE window's frame is a response with its driver's turn-on and turn-off."""
    logic = LogicSpec("BUS", de="DE", baud=BAUD, parity="E")
    req, rsp = bytes.fromhex(fr("010600010003")), bytes.fromhex(fr("010600010003"))  # FC6: the answer echoes
    t_rsp = 1000 + 40 * CHAR
    end = t_rsp + len(rsp) * CHAR
    lines = [rise(t_rsp - 120), fall(end + 25), *burst("rx", t_rsp, rsp), *burst("rx", 1000 + 80 * CHAR, req)]
    events = run(lines, logic)
    info_roles = {"extra": {"channel_roles": logic.roles()}}
    from sniffer.events import CaptureInfo

    info = CaptureInfo(baud=BAUD, parity="E", extra=info_roles["extra"])
    frames = run_events(events, LINE, info=info, directions=roles_of(info))
    # the capture starts with the echo: on a bare line it would pass for a request; DE says it is the answer
    assert [(f.raw, f.role) for f in frames] == [(rsp, "response"), (req, "request")]
    assert frames[0].de_on_ns == ns(t_rsp - 120) - ns(t_rsp)
    assert frames[0].de_off_ns == ns(end + 25) - (ns(t_rsp + 7 * CHAR) + LINE.char_ns)
    assert frames[1].de_on_ns is None and frames[1].de_off_ns is None
    assert " DE -120.0/+25.0us " in frame_line(frames[0], 0) and " DE " not in frame_line(frames[1], 0)


def test_decoder_options_name_the_channels_the_user_gave():
    args = decoder_args(LogicSpec("D1", "D0", "D2", invert=True, baud=19200, parity="E"), LineSettings(19200, "E"))
    joined = " ".join(args)
    assert "counter:data=D2:reset=D2:data_edge=rising:reset_edge=falling" in joined
    assert "uart:rx=D1:tx=D0:baudrate=19200:parity=even:data_bits=8:format=hex:invert_rx=yes:invert_tx=yes" in joined
    assert args.index("-P") < args.index("uart:rx=D1:tx=D0:baudrate=19200:parity=even:data_bits=8:format=hex:"
                                         "invert_rx=yes:invert_tx=yes")  # the DE decoder runs first
