"""Drive models decode what a field engineer needs: names, scaled values, units, faults, rules."""

from __future__ import annotations

from helpers import bursts, fr, run_events

from sniffer.line import LineSettings

L = LineSettings(19200, "E", 1)




def codes_of(f):
    return [a.code for a in f.annotations]


def test_a510_output_frequency_in_hz_and_fault_text():
    # read 2520H..2524H from unit 2: status, fault 1, -, freq cmd 50.00, output 49.98
    req = fr("020325200005")
    rsp = fr("02030a" + "0001" + "0001" + "0000" + "1388" + "1386")
    _, r = run_events(bursts([req, rsp], L), L, devices={2: "a510"})
    pts = {p["address"]: p for p in r.points}
    assert pts[0x2524]["value"] == 49.98 and pts[0x2524]["unit"] == "Hz"
    assert pts[0x2524]["name"] == "Output frequency"
    assert pts[0x2521]["text"] and "unknown" not in pts[0x2521]["text"]
    assert "a510.freq.resolution" in codes_of(r)
    # the same bytes on the high-frequency variant: 0.1 Hz
    _, r = run_events(bursts([req, rsp], L), L, devices={2: "a510-hf"})
    assert {p["address"]: p["value"] for p in r.points}[0x2524] == 499.8


def test_a510_value_over_300hz_switches_resolution():
    req = fr("020325240001")
    rsp = fr("0203027918")  # 31000: impossible at 0.01 Hz
    _, r = run_events(bursts([req, rsp], L), L, devices={2: "a510"})
    assert r.points[0]["value"] == 3100.0 and "a510.freq.high" in codes_of(r)


def test_tds_frequency_in_percent_until_cn02_seen_then_hz():
    read_f = fr("010300250001")
    rsp_f = fr("0103023a98")  # 15000 = 50 % of Cn-02
    read_cn02 = fr("010303010001")
    rsp_cn02 = fr("0103020258")  # Cn-02 = 600 -> 60.0 Hz
    frames = run_events(bursts([read_f, rsp_f, read_cn02, rsp_cn02, read_f, rsp_f], L), L, devices={1: "tds-v8"})
    first, last = frames[1].points[0], frames[5].points[0]
    assert (first["value"], first["unit"]) == (50.0, "%") and "model.scale.pending" in codes_of(frames[1])
    assert frames[3].points[0]["id"] == "Cn-02" and frames[3].points[0]["value"] == 60.0
    assert (last["value"], last["unit"]) == (30.0, "Hz") and "model.scale.pending" not in codes_of(frames[5])


def test_tds_write_rules():
    status_drv = fr("010300200001"), fr("0103020010")  # bit 4 = 1: DRV mode
    write_cn = fr("010603010258")  # Cn-02 = 60.0 Hz while in DRV
    too_many = fr("010300200011")  # 17 registers
    bcast = fr("000600050001")  # broadcast to 0005H (reserved, not 0000H/0001H)
    ro = fr("010600250001")  # write to a monitor register
    frames = run_events(bursts([*status_drv, write_cn, too_many, bcast, ro], L), L, devices={1: "tds-v8", 0: "tds-v8"})
    assert "tds.write.prg_only" in codes_of(frames[2])
    assert "model.request.too_many" in codes_of(frames[3])
    assert "model.broadcast.register" in codes_of(frames[4])
    assert "model.write.read_only" in codes_of(frames[5])


def test_tds_out_of_range_parameter_write():
    f, = run_events(bursts([fr("010603010064")], L), L, devices={1: "tds-v8"})  # Cn-02 = 10.0 Hz < 50.0
    assert "model.value.range" in codes_of(f)


def test_spl_vendor_exception():
    req, rsp = fr("010301210001"), fr("018352")
    _, r = run_events(bursts([req, rsp], L), L, devices={1: "spl"})
    assert r.exception["code"] == 0x52 and r.exception["name"] != "UNKNOWN EXCEPTION"
    assert "model.exception.vendor" in codes_of(r)


def test_readme_model_file_worked_example():
    """docs/models.md's --model-file example, verbatim."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    r = subprocess.run(
        [sys.executable, "-m", "sniffer", "decode", "03031100000440D7", "0303080259012C021C0003C6DB",
         "030610010190DCD4", "038630E3B4", "--model-file", "docs/examples/acme-x1.toml", "--device", "3=acme-x1"],
        capture_output=True, text=True, cwd=root, timeout=60)
    assert r.returncode == 0, r.stderr
    page = (root / "docs" / "models.md").read_text()
    for line in r.stdout.splitlines():
        assert line in page, line
    assert "Active fault=3 [OC — over-current during acceleration]" in r.stdout
