"""Foxglove-native MCAP, on a synthetic line where every frame is known: which values reach /values,
what /annotations says, the `foxglove` metadata, the attachment; the thinning rule of /values.

The capture goes through a real Session into a real MCAP file, read back with the mcap library.
"""

import json
import tomllib

import pytest
from helpers import fr, read_mcap
from mcap.reader import make_reader

from decoders.mapfile import map_file
from decoders.tables import load_map
from sniffer.formats.mcap import foxglove
from sniffer.codes import CRC_MISMATCH
from sniffer.events import CaptureInfo, Chunk, Tick
from sniffer.formats.mcap.foxglove import KEEP_NS, Foxglove
from sniffer.line import LineSettings
from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.formats.mcap.sink import McapSink

S = 1_000_000_000
MS = 1_000_000
LINE = LineSettings(19200, "E", 1)
WALL = 1_764_000_000 * S


def _burst(t: int, data: bytes) -> Chunk:
    return Chunk(t, data, tuple(t + i * LINE.char_ns for i in range(len(data))))


def _bad_crc(hex_body: str) -> bytes:
    b = bytearray.fromhex(fr(hex_body))
    b[-1] ^= 0xFF
    return bytes(b)


# (time in ms, the frame's bytes, what it is); unit 1 is an A510 (--device 1=a510)
LINE_EVENTS = [
    (0, bytes.fromhex(fr("010325240001")), "read Output frequency"),
    (10, bytes.fromhex(fr("0103021386")), "answer 49.98 Hz"),
    (100, bytes.fromhex(fr("010325240001")), "read Output frequency"),
    (110, _bad_crc("01030204D2"), "answer 12.34 Hz with a bad CRC: not a value"),
    (200, bytes.fromhex(fr("010625020BB8")), "write Frequency command 30.00 Hz"),
    (210, bytes.fromhex(fr("010625020BB8")), "its echo: confirmed"),
    (300, bytes.fromhex(fr("0110250100020400010FA0")), "write Operation signal 1, Frequency command 40.00 Hz"),
    (310, bytes.fromhex(fr("019002")), "an exception: nothing written"),
    (400, bytes.fromhex(fr("01102502000102 1194".replace(" ", ""))), "write 45.00 Hz: never answered"),
    (2500, bytes.fromhex(fr("000625021388")), "broadcast write 50.00 Hz: nobody acknowledges it"),
    (2700, bytes.fromhex(fr("0110250200010215 7C".replace(" ", ""))), "write 55.00 Hz"),
    (2710, bytes.fromhex(fr("011025020001")), "acknowledged"),
]


def events():
    out = []
    for t_ms, data, _what in LINE_EVENTS:
        out.append(_burst(t_ms * MS, data))
        out.append(Tick(t_ms * MS + 50 * MS))  # a quiet line: a live source ticks
    out.append(Tick(4000 * MS))
    return out


def capture(tmp_path, spec=None, name="line.mcap"):
    info = CaptureInfo(source="synthetic", port="/dev/ttyUSB7", baud=LINE.baud, parity=LINE.parity,
                       stopbits=LINE.stopbits, time_source="byte", t0_ns=0, wall_anchor_ns=WALL)
    path = tmp_path / name
    spec = spec or CaptureSpec.of(devices={1: "a510"}, foxglove_device="cabinet-3")
    session = Session(spec, EventSource(info, events()), [McapSink(path)])
    session.run()
    assert session.error is None
    return path


def read(path):
    """(summary, metadata {name: map}, attachments, {topic: [(log_time, decoded message)]})."""
    summary, meta, attachments, msgs = read_mcap(path)
    topics: dict[str, list] = {}
    for ch, t, d in msgs:
        topics.setdefault(ch.topic, []).append((t, d))
    return summary, meta, list(attachments.values()), topics


def frame_at(topics, what: str) -> dict:
    """The /frames record of the LINE_EVENTS entry `what` (frames are numbered in line order here)."""
    k = [w for _t, _d, w in LINE_EVENTS].index(what)
    return topics["/frames"][k][1]


def test_only_confirmed_values_reach_the_values_topics(tmp_path):
    _summary, _meta, _att, topics = read(capture(tmp_path))
    values = {t: v for t, v in topics.items() if t.startswith("/values/")}
    assert set(values) == {"/values/u1/Output_frequency", "/values/u1/Frequency_command"}
    assert [(m["value"], m["raw"], m["unit"]) for _t, m in values["/values/u1/Output_frequency"]] == \
        [(49.98, 4998, "Hz")]
    # written: the echoed single write and the acknowledged multiple write; not the exception's, the
    # unanswered one's or the broadcast's
    got = [(t, m["value"], m["frame"]) for t, m in values["/values/u1/Frequency_command"]]
    echo, ack = frame_at(topics, "its echo: confirmed"), frame_at(topics, "acknowledged")
    assert got == [(WALL + 210 * MS, 30.0, echo["index"]), (WALL + 2710 * MS, 55.0, ack["index"])]
    assert frame_at(topics, "write 45.00 Hz: never answered")["points"][0]["value"] == 45.0  # decoded, not a value


def test_annotations_are_a_foxglove_log(tmp_path):
    summary, _meta, _att, topics = read(capture(tmp_path))
    ch = next(c for c in summary.channels.values() if c.topic == "/annotations")
    schema = summary.schemas[ch.schema_id]
    assert (schema.name, schema.encoding, ch.message_encoding) == ("foxglove.Log", "jsonschema", "json")
    logs = [m for _t, m in topics["/annotations"]]
    frames = [m for _t, m in topics["/frames"]]
    bad = frame_at(topics, "answer 12.34 Hz with a bad CRC: not a value")
    crc = next(m for m in logs if m["file"] == CRC_MISMATCH.code)
    assert (crc["level"], crc["name"], crc["line"]) == (4, "u1", bad["index"])
    assert crc["timestamp"] == {"sec": (WALL + 110 * MS) // S, "nsec": (WALL + 110 * MS) % S}
    assert crc["message"].startswith(f"{CRC_MISMATCH.code}: ") and f"#{bad['index']} " in crc["message"]
    # every warning and error of every frame, each info note once per unit and code
    expected = []
    told = set()
    for f in frames:
        for a in f["annotations"]:
            if a["severity"] == "info":
                if (f["unit"], a["code"]) in told:
                    continue
                told.add((f["unit"], a["code"]))
            expected.append((f["index"], a["code"], foxglove.LEVELS[a["severity"]]))
    assert [(m["line"], m["file"], m["level"]) for m in logs] == expected
    assert {lvl for _i, _c, lvl in expected} == {2, 3, 4}
    infos = [f for f in frames if any(a["code"] == "a510.freq.resolution" for a in f["annotations"])]
    units = {f["unit"] for f in infos}  # unit 1 and the broadcast's unit 0
    assert len(infos) > len(units) == sum(m["file"] == "a510.freq.resolution" for m in logs) == 2


def test_foxglove_metadata_names_the_device_and_the_link(tmp_path):
    _s, meta, _att, _topics = read(capture(tmp_path))
    assert meta["foxglove"] == {"deviceName": "cabinet-3", "links": "ttyUSB7", "line": "19200 8E1 modbus-rtu",
                                "sniffer": meta["foxglove"]["sniffer"]}
    assert json.loads(meta["sniffer.capture"]["extra"])["device_name"] == "cabinet-3"
    # without --foxglove-device: this host's name
    import socket

    _s, meta, _att, _topics = read(capture(tmp_path, CaptureSpec.of(devices={1: "a510"}), "host.mcap"))
    assert meta["foxglove"]["deviceName"] == socket.gethostname()


def test_the_register_map_travels_as_an_attachment_that_decodes_without_the_project(tmp_path):
    _s, _meta, attachments, topics = read(capture(tmp_path))
    [att] = attachments
    assert (att.name, att.media_type) == ("a510.registers.toml", "application/toml")
    assert att.log_time == WALL  # with the first frame of the model
    # standard library only: the row of the register read, and the response's bytes
    doc = tomllib.loads(att.data.decode())
    row = next(r for r in doc["registers"] if r["addr"] == 0x2524)
    rsp = frame_at(topics, "answer 49.98 Hz")
    raw = int.from_bytes(bytes.fromhex(rsp["raw"])[3:5], "big")
    assert (row["name"], row["unit"], round(raw * row["scale"], 2)) == ("Output frequency", "Hz", 49.98)
    # and the sniffer loads it as a --model-file map equal to its own
    p = tmp_path / "a510.toml"
    p.write_bytes(att.data)
    from decoders.registry import builtin_decoders

    assert load_map(p).registers == builtin_decoders()["a510"].map.registers


def test_map_files_of_every_kind():
    assert map_file("generic") is None and map_file("no-such-model") is None
    name, media, data = map_file("pd-series")
    doc = json.loads(data)
    assert (name, media) == ("pd-series.tables.json", "application/json")
    assert next(p for p in doc["parameters"] if p["id"] == "PD003")["scale"] == 0.01
    assert {s["label"] for s in doc["status_selectors"]} >= {"Set F", "Out F"}
    name, _media, data = map_file("a510-hf")
    assert name == "a510-hf.registers.toml" and b"0.1 Hz per count" in data.split(b"registers = [")[0]


def test_a_csv_map_is_attached_as_the_toml_it_was_read_into(tmp_path):
    from decoders.mapformats import load_model_file

    csv = tmp_path / "pump.csv"
    csv.write_text("address,name,type,scale,unit,access\n2524H,Output frequency,u16,0.01,Hz,R\n"
                   "2502H,Frequency command,u16,0.01,Hz,RW\n")
    path = capture(tmp_path, CaptureSpec.of(devices={1: "pump"}, model_files=(str(csv),)), "pump.mcap")
    _s, meta, [att], topics = read(path)
    assert (att.name, att.media_type) == ("pump.registers.toml", "application/toml")
    back = tmp_path / "back.toml"
    back.write_bytes(att.data)
    assert load_map(back).registers == load_model_file(str(csv))[0].registers
    assert [m["value"] for _t, m in topics["/values/u1/Output_frequency"]] == [49.98]
    assert json.loads(meta["sniffer.capture"]["extra"])["model_files"] == [str(csv)]


def _record(index, role, value, *, unit=1, pair=None, crc_ok=True, writes=True, name="Output frequency"):
    pts = [] if value is None else [{"name": name, "address": 0x2524, "raw": int(value * 100), "value": value,
                                     "unit": "Hz"}]
    return {"index": index, "unit": unit, "role": role, "crc_ok": crc_ok, "exception": None, "model": "a510",
            "pair": pair, "points": pts, "writes": [["holding", 0x2524, [1]]] if writes else [],
            "annotations": [], "summary": ""}


def _values(fox, records):
    out = []
    for t_ns, rec in records:
        out += [(t, json.loads(d)["value"]) for _topic, t, d in fox.frame(_Rec(rec), t_ns)]
    return out + [(t, json.loads(d)["value"]) for _topic, t, d in fox.finish()]


class _Rec:
    def __init__(self, d):
        self.__dict__.update(d, link="")


def test_values_are_thinned_without_changing_their_plot():
    """A change, the sample before it, one sample every KEEP_NS, and the last one at the end."""
    fox = Foxglove(CaptureInfo())
    series = [0, 1, 2, 3, 4, 5, 6]  # polls every second
    vals = [50.0, 50.0, 50.0, 45.0, 45.0, 45.0, 40.0]
    recs = [(k * S, _record(k, "response", v)) for k, v in zip(series, vals)]
    got = _values(fox, recs)
    assert got == [(0, 50.0), (2 * S, 50.0), (3 * S, 45.0), (5 * S, 45.0), (6 * S, 40.0)]
    # what a plot draws between the polls is the same as with every sample: linear interpolation of
    # the thinned series equals the full series at every poll
    for t, v in zip(series, vals):
        assert _interpolate(got, t * S) == v

    fox = Foxglove(CaptureInfo())
    steady = [(k * S, _record(k, "response", 7.0)) for k in range(26)]
    got = _values(fox, steady)
    assert [t for t, _v in got] == [0, KEEP_NS, 2 * KEEP_NS, 25 * S]


def _interpolate(points, t):
    for (t0, v0), (t1, v1) in zip(points, points[1:]):
        if t0 <= t <= t1:
            return v0 if t1 == t0 else v0 + (v1 - v0) * (t - t0) / (t1 - t0)
    raise AssertionError(t)


def test_a_window_ring_record_gives_the_same_messages_as_its_frame(tmp_path):
    """A trigger window writes encoded /frames records: the record path gives the Frame path's messages."""
    path = capture(tmp_path)
    _s, _meta, _att, topics = read(path)
    fox = Foxglove(CaptureInfo(t0_ns=0, wall_anchor_ns=WALL))
    out = []
    with open(path, "rb") as fh:
        for _schema, _ch, msg in make_reader(fh).iter_messages(topics=["/frames"]):
            out += fox.record(msg.data, msg.log_time - WALL)
    out += fox.finish()
    again = {}
    for topic, t, data in out:
        again.setdefault(topic, []).append((WALL + t, json.loads(data)))
    assert again == {t: v for t, v in topics.items() if t.startswith(("/values/", "/annotations"))}


@pytest.mark.parametrize("bad", ["", "  ", "a\nb", "x" * 201])
def test_a_bad_device_name_is_one_line(bad, capsys):
    from sniffer.cli import main

    assert main(["export", "x.mcap", "--to", "mcap", "--out", "y.mcap", "--foxglove-device", bad]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--foxglove-device" in err


def test_the_device_name_reaches_the_capture_process():
    spec = CaptureSpec.of(baud=19200, port="/dev/ttyUSB0", out="x.mcap", foxglove_device="cab 3")
    assert CaptureSpec.decode(spec.encode()) == spec


def test_several_links_each_get_their_own_values_and_the_metadata_names_them(tmp_path):
    """A unit 1 on each of two links: two topics, named for the link; the log names the link."""
    from helpers import bursts

    def on(link, chunks):
        return [Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link) for c in chunks]

    a = on("ttyUSB0", bursts([fr("010325240001"), fr("0103021386"), fr("010325240001"), _bad_crc("01030204D2").hex()],
                             LINE))
    b = on("ttyUSB1+ttyUSB2", bursts([fr("010325240001"), fr("01030203E8")], LINE, t0=10**6))
    info = CaptureInfo(source="synthetic", baud=LINE.baud, parity="E", stopbits=1, t0_ns=0, wall_anchor_ns=WALL,
                       links=[{"name": "ttyUSB0", "ports": ["/dev/ttyUSB0"], "tap": False},
                              {"name": "ttyUSB1+ttyUSB2", "ports": ["/dev/ttyUSB1", "/dev/ttyUSB2"], "tap": True}])
    path = tmp_path / "links.mcap"
    spec = CaptureSpec.of(devices={1: "a510"}, foxglove_device="plant")
    evs = sorted(a + b, key=lambda c: c.t_ns) + [Tick(2 * S)]
    Session(spec, EventSource(info, evs), [McapSink(path)]).run()
    summary, meta, _att, topics = read(path)
    assert meta["foxglove"]["links"] == "ttyUSB0, ttyUSB1+ttyUSB2"
    assert meta["foxglove"]["line"] == "ttyUSB0: 19200 8E1 modbus-rtu; ttyUSB1+ttyUSB2: 19200 8E1 modbus-rtu"
    assert [m["value"] for _t, m in topics["/values/ttyUSB0/u1/Output_frequency"]] == [49.98]
    assert [m["value"] for _t, m in topics["/values/ttyUSB1_ttyUSB2/u1/Output_frequency"]] == [10.0]
    ch = next(c for c in summary.channels.values() if c.topic == "/values/ttyUSB1_ttyUSB2/u1/Output_frequency")
    assert (ch.metadata["link"], ch.metadata["unit"], ch.metadata["model"]) == ("ttyUSB1+ttyUSB2", "1", "a510")
    crc = next(m for _t, m in topics["/annotations"] if m["file"] == CRC_MISMATCH.code)
    assert crc["name"] == "ttyUSB0/u1"
