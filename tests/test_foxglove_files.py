"""Foxglove-native MCAP on simulated captures, through the CLI, read back with the mcap library.

Every channel's messages are validated against its own schema record (jsonschema); /values is held
against /frames (a register's value at each confirmed frame is the frame's, and no value comes from
anywhere else); and the files the other commands write from such a capture (export, a trigger
window, repair) are Foxglove-native too and still replay.
"""

import bisect
import json
import math

import jsonschema
import pytest
from helpers import frames_of, read_mcap as read

from sniffer.cli import main

DEVICE = "bench-7"


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    d = tmp_path_factory.mktemp("foxglove")
    out = {}
    for scenario, seconds in (("a510", 20), ("errors", 20), ("pd-series", 10)):
        p = d / f"{scenario}.mcap"
        assert main(["simulate", "--scenario", scenario, "--duration", str(seconds), "--seed", "3", "--out", str(p),
                     "--foxglove-device", DEVICE]) == 0
        out[scenario] = p
    return out


def topic_messages(msgs, prefix):
    out: dict[str, list] = {}
    for ch, t, d in msgs:
        if ch.topic.startswith(prefix):
            out.setdefault(ch.topic, []).append((t, d))
    return out


@pytest.mark.parametrize("scenario", ["a510", "errors", "pd-series"])
def test_every_message_fits_its_channels_schema(captures, scenario):
    summary, meta, _att, msgs = read(captures[scenario])
    validators = {}
    for cid, ch in summary.channels.items():
        schema = summary.schemas[ch.schema_id]
        assert (schema.encoding, ch.message_encoding) == ("jsonschema", "json"), ch.topic
        doc = json.loads(schema.data)
        cls = jsonschema.validators.validator_for(doc, default=jsonschema.Draft202012Validator)
        cls.check_schema(doc)
        validators[cid] = cls(doc)
    counts: dict[str, int] = {}
    for ch, _t, d in msgs:
        validators[ch.id].validate(d)
        kind = ch.topic if not ch.topic.startswith("/values/") else "/values"
        counts[kind] = counts.get(kind, 0) + 1
    assert counts["/values"] > 10 and counts["/frames"] > 50
    assert meta["foxglove"]["deviceName"] == DEVICE
    if scenario != "pd-series":
        assert counts["/annotations"] > 0


def _confirmed(frames):
    """(log time, frame record, its values): a CRC-good response that wrote its unit's register shadow
    (`writes`), with the points of the registers it wrote (a write's from its request)."""
    by_index = {}
    for t, r in frames:
        by_index[r["index"]] = r
        if r["role"] != "response" or not r["writes"] or not r["crc_ok"] or r["exception"] or not r["unit"]:
            continue
        written = {a for _table, start, raws in r["writes"] for a in range(start, start + len(raws))}
        req = by_index.get(r["pair"])
        points = {(p["name"], p["address"]): p for p in (req["points"] if req else []) + r["points"]}
        yield t, r, [p for p in points.values() if p["address"] in written and "part" not in p]


@pytest.mark.parametrize("scenario", ["a510", "errors", "pd-series"])
def test_values_draw_what_the_frames_say(captures, scenario):
    summary, _meta, _att, msgs = read(captures[scenario])
    frames = [(t, d) for ch, t, d in msgs if ch.topic == "/frames"]
    values = topic_messages(msgs, "/values/")
    topic_of = {}
    for ch in summary.channels.values():
        if ch.topic.startswith("/values/"):
            m = ch.metadata
            topic_of[(int(m["unit"]), m["name"], int(m["address"]))] = ch.topic
    seen = set()
    checked = 0
    for t, r, points in _confirmed(frames):
        for p in points:
            topic = topic_of[(r["unit"], p["name"], p["address"])]
            last = [d for tv, d in values[topic] if tv <= t][-1]  # the plot's value at this frame
            raw = p["raw"] if isinstance(p["raw"], int) else None  # a string's hex stays in /frames
            assert (last.get("raw"), last.get("unit")) == (raw, p["unit"]), (topic, r["index"])
            if isinstance(p["value"], (int, float)) and math.isfinite(p["value"]):
                assert last["value"] == p["value"]
            else:
                assert "value" not in last and last.get("text") == (p.get("text") or p["value"])
            seen.add(r["index"])
            checked += 1
    assert checked > 50
    assert all(d["frame"] in seen for v in values.values() for _t, d in v)  # nothing from other frames
    bad = {r["index"] for _t, r in frames if r["crc_ok"] is False or r["exception"]}
    if scenario == "errors":
        assert bad and not bad & {d["frame"] for v in values.values() for _t, d in v}


def test_export_and_replay_of_a_foxglove_capture(captures, tmp_path, capsys):
    src = captures["a510"]
    out = tmp_path / "again.mcap"
    assert main(["export", str(src), "--to", "mcap", "--out", str(out)]) == 0
    s1, m1, a1, msgs1 = read(src)
    s2, m2, a2, msgs2 = read(out)
    assert m2["foxglove"]["deviceName"] == DEVICE  # the station that captured it, not this one
    assert {k: (a.media_type, a.data) for k, a in a1.items()} == {k: (a.media_type, a.data) for k, a in a2.items()}
    assert list(a1) == ["a510.registers.toml"]

    def fox(msgs):
        return [(ch.topic, t, d) for ch, t, d in msgs if ch.topic.startswith(("/values/", "/annotations"))]

    assert sorted(fox(msgs1), key=str) == sorted(fox(msgs2), key=str)
    capsys.readouterr()
    assert main(["replay", str(src), "--format", "jsonl"]) == 0
    first = capsys.readouterr().out
    assert main(["replay", str(out), "--format", "jsonl"]) == 0
    assert capsys.readouterr().out == first and first.count("\n") > 100
    named = tmp_path / "named.mcap"
    assert main(["export", str(src), "--to", "mcap", "--out", str(named), "--foxglove-device", "lab bench"]) == 0
    assert read(named)[1]["foxglove"]["deviceName"] == "lab bench"


def foxglove_native_alone(path):
    """A part of the a510 capture written as a file of its own (a window, a segment): compact (no /frames,
    /raw batched), every message fitting its channel's schema, the device, the map, values that all come
    from the frames it replays to alone.  Its messages."""
    summary, meta, att, msgs = read(path)
    assert meta["foxglove"]["deviceName"] == DEVICE and list(att) == ["a510.registers.toml"]
    raw = [ch for ch in summary.channels.values() if ch.topic == "/raw"]
    assert [ch.metadata["sniffer.format"] for ch in raw] == ["2"]
    assert "/frames" not in {ch.topic for ch in summary.channels.values()}
    validators = {}
    for cid, ch in summary.channels.items():
        doc = json.loads(summary.schemas[ch.schema_id].data)
        validators[cid] = jsonschema.validators.validator_for(doc, default=jsonschema.Draft202012Validator)(doc)
    for ch, _t, d in msgs:
        validators[ch.id].validate(d)
    # a value's frame is the capture's number of a frame this file replays to (numbered from 0 when it
    # replays alone), at the value's time: one offset for all
    from sniffer.formats.mcap.reader import open_mcap

    info = open_mcap(path)[0]
    at = {info.wall_anchor_ns + round(r["t"] * 1e9): r["index"] for r in frames_of(path)}  # log time -> number
    times = sorted(at)
    values = topic_messages(msgs, "/values/")
    offsets = set()
    for v in values.values():
        for t, d in v:
            i = bisect.bisect_left(times, t - 1000)
            assert i < len(times) and abs(times[i] - t) < 1000, (t, d)  # a frame of the file at the value's time
            offsets.add(d["frame"] - at[times[i]])
    assert values and len(offsets) == 1
    return msgs


def test_trigger_windows_are_foxglove_native(captures, tmp_path):
    src = captures["a510"]
    windows = tmp_path / "w"
    windows.mkdir()
    assert main(["replay", str(src), "--quiet", "--trigger", "fault", "--pre", "1s", "--post", "1s",
                 "--windows", str(windows)]) == 0
    files = sorted(windows.glob("*.mcap"))
    assert files
    for f in files:
        msgs = foxglove_native_alone(f)
        logs = [d for ch, _t, d in msgs if ch.topic == "/annotations"]
        assert any(d["file"] == "model.fault" and d["level"] == 4 for d in logs)
        assert main(["replay", str(f), "--quiet"]) == 0


def test_a_repaired_capture_keeps_its_foxglove_parts(captures, tmp_path):
    data = captures["a510"].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    fixed = tmp_path / "fixed.mcap"
    assert main(["repair", str(cut), "-o", str(fixed)]) == 0
    _s, meta, att, msgs = read(fixed)
    assert meta["foxglove"]["deviceName"] == DEVICE
    assert att["a510.registers.toml"].data == read(captures["a510"])[2]["a510.registers.toml"].data
    assert topic_messages(msgs, "/values/") and topic_messages(msgs, "/annotations")
    assert main(["replay", str(fixed), "--quiet"]) == 0


def test_pd_series_tables_are_attached(captures):
    _s, _meta, att, msgs = read(captures["pd-series"])
    assert list(att) == ["pd-series.tables.json"] and att["pd-series.tables.json"].media_type == "application/json"
    doc = json.loads(att["pd-series.tables.json"].data)
    assert doc["model"] == "pd-series" and any(p["id"] == "PD003" for p in doc["parameters"])
    assert any(t.startswith("/values/u1/") for t in topic_messages(msgs, "/values/"))


def test_the_docs_take_the_register_map_out_and_replay_decodes_with_it(captures, tmp_path, monkeypatch, capsys):
    """docs/foxglove.md's snippet, run as written on a capture: the map it writes is a --model-file."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "foxglove.md").read_text()
    snippet = doc.split("```python\n", 1)[1].split("```", 1)[0]
    assert "cab3.mcap" in snippet
    monkeypatch.chdir(tmp_path)
    exec(compile(snippet.replace("cab3.mcap", str(captures["a510"])), "foxglove.md", "exec"), {})
    assert "a510.registers.toml application/toml" in capsys.readouterr().out
    assert main(["replay", str(captures["a510"]), "--format", "jsonl", "--model-file", "a510.registers.toml"]) == 0
    recs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert any(p["name"] == "Output frequency" and p["unit"] == "Hz" for r in recs for p in r["points"])


def test_frames_and_their_records_give_the_same_foxglove_messages(captures):
    """The capture's frames (generic register blocks read without building points) and their /frames
    records (a trigger window's path) give the same /values and /annotations."""
    from sniffer.events import CaptureInfo
    from sniffer.formats.mcap.foxglove import Foxglove

    _s, _meta, _att, msgs = read(captures["errors"])
    fox = Foxglove(CaptureInfo())  # a simulated capture: t0 and the wall clock's anchor are 0
    out = []
    for ch, t, d in msgs:
        if ch.topic == "/frames":
            out += fox.record(json.dumps(d).encode(), t)
    out += fox.finish()
    again = [(topic, t, json.loads(data)) for topic, t, data in out]
    written = [(ch.topic, t, d) for ch, t, d in msgs if ch.topic.startswith(("/values/", "/annotations"))]
    assert len(again) > 1000 and sorted(again, key=str) == sorted(written, key=str)


def foxglove_reads(schema: dict, where: str = "") -> list[str]:
    """What Foxglove's JSON Schema reader (parseJsonSchema of its MCAP support, as published) refuses in a
    channel's schema: an object's every field needs one type (or a oneOf of numeric constants), an
    array's items one type that is not an array; strings at most base64-encoded."""
    out = []
    if schema.get("type") != "object":
        return [f"{where or 'the schema'}: not an object"]
    for name, field in (schema.get("properties") or {}).items():
        at = f"{where}.{name}" if where else name
        if isinstance(field.get("oneOf"), list):
            if not all(isinstance(alt.get("const"), (int, float)) for alt in field["oneOf"]):
                out.append(f"{at}: oneOf of other than numbers")
            continue
        kind = field.get("type")
        if kind == "object":
            out += foxglove_reads(field, at)
        elif kind == "array":
            item = field.get("items") or {}
            if item.get("type") == "object":
                out += foxglove_reads(item, at + "[]")
            elif item.get("type") not in ("boolean", "string", "number", "integer"):
                out.append(f"{at}: array of {item.get('type')!r}")
        elif kind not in ("boolean", "string", "number", "integer"):
            out.append(f"{at}: type {kind!r}")
        elif field.get("contentEncoding") not in (None, "base64"):
            out.append(f"{at}: contentEncoding {field['contentEncoding']!r}")
    return out


def test_foxglove_reads_the_schemas_of_its_panels_topics(captures):
    summary, _meta, _att, _msgs = read(captures["a510"])
    names = set()
    for ch in summary.channels.values():
        if ch.topic.startswith("/values/") or ch.topic == "/annotations":
            schema = summary.schemas[ch.schema_id]
            assert foxglove_reads(json.loads(schema.data)) == [], ch.topic
            names.add(schema.name)
    assert names == {"sniffer.Value", "foxglove.Log"}
    # the rule finds what it looks for
    assert foxglove_reads({"type": "object", "properties": {"a": {"type": ["number", "null"]}, "b": {},
                                                            "c": {"type": "array", "items": {"type": "array"}}}}) \
        == ["a: type ['number', 'null']", "b: type None", "c: array of 'array'"]


def test_rotated_segments_are_foxglove_native(captures, tmp_path):
    """Each segment of `--rotate` is an MCAP of its own: its metadata, its register map, its values."""
    folder = tmp_path / "cab3"
    assert main(["replay", str(captures["a510"]), "--quiet", "--rotate", "5s", "--out", str(folder)]) == 0
    segments = sorted(folder.glob("*.mcap"))
    assert len(segments) >= 3
    for seg in segments:
        foxglove_native_alone(seg)
