"""Issue 10, section 3: what the independent read of the manuals found (D1-D9), case by case.

Every frame goes through the real pipeline (framer, pairer, registry, the built-in maps) or the
real CLI; the expected texts are the manuals' (cited next to each case).
"""

from __future__ import annotations

import json

import pytest
from helpers import bursts, fr, run_events

from decoders.registry import builtin_decoders
from sniffer import cli
from sniffer.framing.crc import lrc
from sniffer.line import LineSettings

L = LineSettings(19200, "N", 1)
L_ASCII = LineSettings(9600, "E", 1, databits=7)


def decode(frames: list[str], model: str, unit: int = 1, line: LineSettings = L, protocol: str = "modbus-rtu"):
    return run_events(bursts(frames, line), line, devices={unit: model}, protocol=protocol)


def notes(f, code: str) -> list[str]:
    return [a.detail for a in f.annotations if a.code == code]


def asc(hex_body: str) -> str:
    """A Modbus ASCII frame's characters (as hex of the wire bytes) for `hex_body` plus its LRC."""
    b = bytes.fromhex(hex_body)
    return (b":" + (b + bytes([lrc(b)])).hex().upper().encode() + b"\r\n").hex()


# ---- exception texts: one table per model, hex codes, the standard meaning as a note ----------

def test_tds_04h_is_the_manuals_crc_error_with_the_standard_meaning_as_a_note():
    # zh-2021 8 l.710 / en 8 l.635: 04H "CRC_16 Error" (redefines standard 04H)
    req, rsp = decode([fr("010300200001"), fr("018304")], "tds-v8")
    assert rsp.exception == {"code": 4, "name": "CRC_16 Error"}
    assert rsp.summary == "exception 04H CRC_16 Error (read holding registers)"
    (detail,) = notes(rsp, "modbus.exception")
    assert detail.startswith("04H CRC_16 Error: CRC reception differs from calculated CRC")
    assert detail.endswith("standard Modbus 04H: SERVER DEVICE FAILURE")
    assert "4 SERVER" not in detail and not notes(rsp, "modbus.exception.unlisted")


def test_spl_vendor_codes_named_by_the_manual_in_hex():
    # SPL 4. Exception Code, lines 244-249: 51H-55H
    for code, name in ((0x51, "FUNCTION CODE ERROR"), (0x52, "REGISTER ENCODING ERROR"), (0x55, "WRITE MODE ERROR")):
        _, rsp = decode([fr("010301200001"), fr(f"0183{code:02X}")], "spl")
        assert rsp.exception == {"code": code, "name": name}
        assert rsp.summary == f"exception {code:02X}H {name} (read holding registers)"
        assert notes(rsp, "modbus.exception")[0].startswith(f"{code:02X}H {name}")
        assert notes(rsp, "model.exception.vendor") and not notes(rsp, "modbus.exception.unlisted")
        assert "UNKNOWN" not in rsp.summary and str(code) not in notes(rsp, "modbus.exception")[0].split()[0]


@pytest.mark.parametrize("model, code, name", [
    ("spl", 0x02, "ILLEGAL DATA ADDRESS"),   # SPL lists only 51H-55H
    ("spl", 0x20, "UNDOCUMENTED 20H"),       # printed in an 08H example only, not in the table
    ("a510", 0x51, "UNKNOWN EXCEPTION"),     # A510 lists 01-04 (l.213-217); 51H is in its figure only
    ("tds-v8", 0x06, "SERVER DEVICE BUSY"),  # TDS-V8 lists 01-04, 21H, 22H
    ("generic", 0x51, "UNKNOWN EXCEPTION"),  # generic: the Modbus standard's table
])
def test_a_code_the_units_manual_does_not_list_is_a_warning(model, code, name):
    _, rsp = decode([fr("010300000001"), fr(f"0183{code:02X}")], model)
    assert rsp.exception["name"] == name
    (why,) = [a for a in rsp.annotations if a.code == "modbus.exception.unlisted"]
    assert why.severity == "warning" and why.detail.startswith(f"{code:02X}H is not")


def test_listed_codes_are_not_flagged():
    for model, code in (("generic", 0x02), ("a510", 0x04), ("tds-v8", 0x21), ("spl", 0x54)):
        _, rsp = decode([fr("010300000001"), fr(f"0183{code:02X}")], model)
        assert not notes(rsp, "modbus.exception.unlisted"), (model, code)


def test_a_user_map_with_vendor_codes_only_keeps_the_standard_ones(tmp_path):
    from decoders.registry import default_registry
    from sniffer.events import CaptureInfo
    from sniffer.capture.pipeline import Pipeline

    reg = default_registry({3: "acme-x1"}, model_files=["docs/examples/acme-x1.toml"])
    p = Pipeline(CaptureInfo(), L, reg)
    out = []
    for ev in bursts([fr("030300000001"), fr("038302"), fr("030300000001"), fr("038330"),
                      fr("030300000001"), fr("038341")], L):
        out += p.feed(ev)
    out += p.finish()
    std, vendor, neither = out[1], out[3], out[5]
    assert not notes(std, "modbus.exception.unlisted") and std.exception["name"] == "ILLEGAL DATA ADDRESS"
    assert vendor.exception["name"] == "PARAMETER LOCKED" and not notes(vendor, "modbus.exception.unlisted")
    assert notes(neither, "modbus.exception.unlisted")


# ---- fault and alarm texts: one form, names kept --------------------------------------------

def test_fault_texts_in_one_form_for_every_model():
    # A510 2521H fault 5 "OL1" (l.315), SPL 0121H 21 "Motor over load (OL1)" (l.1200),
    # TDS-V8 0021H bit 4 "Motor Over Load Fault (OL1)" (en l.373)
    _, a = decode([fr("010325210001"), fr("0103020005")], "a510")
    _, s = decode([fr("010301210001"), fr("0103020015")], "spl")
    _, t = decode([fr("010300210001"), fr("0103020010")], "tds-v8")
    assert a.points[0]["text"] == "OL1 — Motor overload"
    assert s.points[0]["text"] == "OL1 — Motor over load"
    assert t.points[0]["text"] == "OL1 — Motor overload fault"


def test_a510_fault_table_has_no_editorial_placeholder():
    m = builtin_decoders()["a510"].map
    texts = {code: m.enum_text("fault_code", code) for code in m.enums["fault_code"]}
    assert texts[0] == "No fault"
    assert not any("presumably" in t or t.startswith(" ") for t in texts.values())
    blank = [c for c, t in texts.items() if t == "no text in the manual"]
    assert len(blank) == 26 and 31 in blank and 61 in blank  # printed blank in the manual (l.310-347)
    assert texts[38] == "CF07" and texts[2] == "OC — Over current"


def test_every_fault_and_alarm_entry_has_a_section():
    for mid in ("a510", "spl"):
        m = builtin_decoders()[mid].map
        for name in ("fault_code", "alarm_code", "error_code"):
            for code, e in m.enums.get(name, {}).items():
                assert e.get("section"), (mid, name, code)
    tds = builtin_decoders()["tds-v8"].map
    assert "OC — Over-current fault" in tds.bits_text("fault_low", 0b10)
    assert tds.bits_text("alarm_word", 1 << 5) == "bb — External base block"


def test_spl_0122h_input_bits_keep_their_terminal_names():
    # 5.5.2 lines 1203-1213: bits 0-6 "Terminal S1..AIN 1 : OFF", bit A "R1A ON"
    _, r = decode([fr("010301220001"), fr("0103020405")], "spl")  # S1, S3, R1A
    text = r.points[0]["text"]
    assert text.startswith("S1 OFF, S3 OFF") and "R1A ON" in text
    _, r = decode([fr("010301010001"), fr("0103020060")], "spl")  # 0101H bits 5, 6: S1, S2 commands
    assert "S1 ON, S2 ON" in r.points[0]["text"]


def test_spl_00f6h_is_in_the_map():
    m = builtin_decoders()["spl"].map
    r = m.registers[0x00F6]
    assert "1769" in r.section and r.access == "reserved"
    req, _ = decode([fr("010300F50003"), fr("010306000000000000")], "spl")
    assert not notes(req, "model.register.unknown")
    w, _ = decode([fr("010600F60001"), fr("010600F60001")], "spl")
    assert notes(w, "model.write.reserved") and not notes(w, "model.register.unknown")


# ---- summaries name addresses as the manual does --------------------------------------------

def test_summaries_in_hex_and_parameter_ids():
    req, rsp = decode([fr("010325200010"), fr("010320" + "0000" * 16)], "a510")
    assert req.summary == "read 2520H..252FH (16)"
    req, rsp = decode([fr("011001000002040001000A"), fr("011001000002")], "tds-v8")
    assert rsp.summary == "wrote An-01..An-02 (2)"
    req, _ = decode([fr("010303010001"), fr("0103020258")], "tds-v8")
    assert req.summary == "read Cn-02 (1)"
    req, rsp = decode([fr("010399990001"), fr("0103020001")], "a510")
    assert req.summary == "read 9999H (1)" and rsp.points[0]["name"] == "holding[9999H]"
    req, _ = decode([fr("010325200010"), fr("010320" + "0000" * 16)], "generic")
    assert req.summary == "read holding 9504..9519 (16)"  # generic keeps decimal


# ---- limits the manuals state ---------------------------------------------------------------

def test_frame_longer_than_80_bytes_is_flagged_a510_and_spl():
    # A510 l.8 / SPL line 13: "maximum frame length is 80 bytes"; a 38-register reply is 81 bytes
    for model in ("a510", "spl"):
        _, rsp = decode([fr("010325200026"), fr("01034C" + "0000" * 38)], model)
        assert len(rsp.raw) == 81
        (d,) = notes(rsp, "model.frame.too_long")
        assert d.startswith("81 bytes on the wire (manual: at most 80")
        _, ok = decode([fr("010325200025"), fr("01034A" + "0000" * 37)], model)
        assert len(ok.raw) == 79 and not notes(ok, "model.frame.too_long")
    _, g = decode([fr("010325200026"), fr("01034C" + "0000" * 38)], "tds-v8")
    assert not notes(g, "model.frame.too_long")  # TDS-V8 states no frame limit


def test_frame_limit_counts_ascii_characters():
    # 16 registers in ASCII: 1 + 2 * (3 + 32 + 1) + 2 = 75 characters; 17: 79; 18: 83
    got = {}
    for n in (17, 18):
        req, rsp = decode([asc(f"01032520{n:04X}"), asc(f"0103{2 * n:02X}" + "0000" * n)], "a510",
                          line=L_ASCII, protocol="modbus-ascii")
        got[n] = (len(rsp.raw), bool(notes(rsp, "model.frame.too_long")))
    assert got == {17: (79, False), 18: (83, True)}


def test_tds_loop_test_only_subfunction_0000h():
    # zh-2021 / en 8: "Function code is 08H but sub-Function code is not 0000H" -> exception 01H
    bad, _ = decode([fr("010800040000"), fr("018801")], "tds-v8")
    (d,) = notes(bad, "model.diagnostics.subfunction")
    assert "0004H" in d and "0000H" in d
    good, _ = decode([fr("01080000A537"), fr("01080000A537")], "tds-v8")
    assert not notes(good, "model.diagnostics.subfunction")
    other, _ = decode([fr("010800040000"), fr("010800040000")], "generic")
    assert not notes(other, "model.diagnostics.subfunction")


def test_a510_torque_8000h_is_not_available_not_minus_400_percent():
    # l.260: 2503H torque command, +/-8192 = +/-100 % of rated torque
    _, r = decode([fr("010325030001"), fr("0103028000")], "a510")
    pt = r.points[0]
    assert pt["value"] is None and pt["raw"] == 0x8000 and "not available" in pt["text"]
    assert "-400" not in r.summary and "n/a" in r.summary
    (a,) = [a for a in r.annotations if a.code == "model.value.not_available"]
    assert a.severity == "warning" and (a.start, a.end) == (3, 5)
    _, r = decode([fr("010325030001"), fr("0103022000")], "a510")  # 8192 = 100 %
    assert r.points[0]["value"] == 100.0 and not notes(r, "model.value.not_available")


# ---- `sniffer decode`: ASCII arguments and no made-up timing --------------------------------

def run_decode(capsys, *argv) -> tuple[int, list[dict], str]:
    rc = cli.main(["decode", *argv, "--format", "jsonl"])
    cap = capsys.readouterr()
    return rc, [json.loads(line) for line in cap.out.splitlines()], cap.err


def test_decode_ascii_accepts_characters_and_hex(capsys):
    body = "010300000001"
    chars = ":" + body + f"{lrc(bytes.fromhex(body)):02X}"
    wire_hex = asc(body)
    forms = [chars, chars[1:], wire_hex, chars[1:].lower()]
    rc, recs, _ = run_decode(capsys, "--protocol", "modbus-ascii", *forms)
    assert rc == 0 and len(recs) == 4
    assert all(r["crc_ok"] and r["summary"] == "read holding 0..0 (1)" for r in recs)
    assert {r["raw"] for r in recs} == {bytes.fromhex(wire_hex).hex()}


def test_decode_ascii_refuses_what_is_neither(capsys):
    rc = cli.main(["decode", "--protocol", "modbus-ascii", "01xx03"])
    err = capsys.readouterr().err
    assert rc == 2 and "not a frame" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_decode_has_no_made_up_timing(capsys):
    rc, recs, _ = run_decode(capsys, "010300000002C40B", "010304000100022A32")
    assert rc == 0 and recs[1]["pair"] == 0
    assert all(r["time_source"] == "none" and r["latency_ms"] is None for r in recs)
    # PD-series: two frames 'typed in' get no "< 50 ms quiet" note and no latency
    rc, recs, _ = run_decode(capsys, "--protocol", "pd-rtu", "010403010000a18e", "010403010000a18e")
    assert rc == 0 and recs[1]["summary"].startswith("Out F")
    assert not [a for r in recs for a in r["annotations"] if a["code"] == "pd.timing.quiet"]
    assert recs[1]["latency_ms"] is None
    # an unanswered request says so without a made-up wait
    rc, recs, _ = run_decode(capsys, "010300000002C40B", "010300000002C40B")
    details = [a["detail"] for r in recs for a in r["annotations"] if a["code"] == "pair.no_response"]
    assert details and all(" ms" not in d for d in details)


def test_decode_text_shows_no_time(capsys):
    assert cli.main(["decode", "010300000002C40B", "010304000100022A32"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and all(line.split()[0] == "-" for line in lines) and "ms" not in lines[1]


# ---- the manual's function codes and value limits (found by an outside review) ----------------
@pytest.mark.parametrize("model", ["a510", "tds-v8", "spl"])
def test_a_function_code_the_manual_does_not_list_is_flagged(model):
    out = decode([fr("010100000008"), fr("01050000ff00"), fr("010400000001"), fr("010300000001")], model)
    reqs = [f for f in out if f.role == "request"]
    assert [bool(notes(f, "model.function.unsupported")) for f in reqs] == [True, True, True, False]
    assert "03H, 06H, 08H, 10H" in notes(reqs[0], "model.function.unsupported")[0]


def test_generic_takes_every_function_code():
    out = run_events(bursts([fr("010100000008")], L), L)
    assert not notes(out[0], "model.function.unsupported")


def test_a510_torque_past_100_percent_is_out_of_range():
    out = decode([fr("010625037fff"), fr("010625032000"), fr("01062503e000")], "a510")
    reqs = [f for f in out if f.role == "request"]
    assert [bool(notes(f, "model.value.range")) for f in reqs] == [True, False, False]


# ---- drive trips are problems (issue 11): the fault / alarm registers of each manual ----------
@pytest.mark.parametrize("model, read, answer, code, text", [
    ("a510", "010325210001", "010302000c", "model.fault", "fault: Input Phase Loss"),
    ("a510", "010325280001", "0103020003", "model.alarm", "alarm: OL2 — Inverter overload"),
    ("spl", "010301210001", "0103020015", "model.fault", "fault: OL1 — Motor over load"),
    ("tds-v8", "010300210001", "0103020002", "model.fault", "fault: "),
    ("tds-v8", "010300230001", "0103020001", "model.alarm", "alarm: "),
])
def test_a_fault_or_alarm_the_drive_reports_is_a_problem(model, read, answer, code, text):
    out = decode([fr(read), fr(answer)], model)
    assert notes(out[1], code) and notes(out[1], code)[0].startswith(text)
    zero = fr(answer[:6] + "0000")
    out = decode([fr(read), zero], model)
    assert not notes(out[1], "model.fault") and not notes(out[1], "model.alarm")  # 0: no trip
