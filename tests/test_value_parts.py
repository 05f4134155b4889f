"""Every part of a capture starts with what the decoders knew where it was cut, and every view keeps a
provisional value apart: rotated segments replayed alone, a folder with a segment missing, a trigger
window, the files of a fleet dataset and its queries, MQTT topics and Foxglove channels.

The line: a simulated TDS-V8 pair whose PLC reads Cn-02 (every frequency is a fraction of it) only 10 s
in, recorded whole and as 5 s segments (the capture's own session, as `live --rotate` writes them).
"""

from __future__ import annotations

import json
import shutil
from collections import defaultdict

import pytest
from helpers import decoded, simulated

from sniffer.cli import main
from sniffer.sources.files import FileSource

KEY = "decoder_state"  # what a part starts with, in its metadata (decoders/carry.py)
LATE_CN02 = ("--scenario", "tds-v8", "--param", "startup_polls=()", "--duration", "30", "--seed", "3")
CN02 = {"769": 600}  # Cn-02 (0301H) = 60.0 Hz, as the simulated drives hold it


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    return simulated(tmp_path_factory, "tds.mcap", *LATE_CN02)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return simulated(tmp_path_factory, "cab", *LATE_CN02, "--rotate", "5s")


def segments(folder) -> list:
    segs = sorted(folder.glob("*.mcap"))
    assert len(segs) == 6
    return segs


def points(frames) -> list[tuple]:
    return [(f.unit, p["name"], p.get("unit"), p.get("value")) for f in frames for p in f.points]


def one_unit_per_name(pts) -> dict:
    units = defaultdict(set)
    for unit, name, eng, _v in pts:
        units[(unit, name)].add(eng)
    return {k: v for k, v in units.items() if len(v) > 1}


def state_of(path) -> dict:
    src = FileSource(str(path))
    try:
        return src.open().extra.get(KEY) or {}
    finally:
        src.close()


def test_each_segment_replayed_alone_scales_and_names_its_values_as_the_capture_did(folder):
    _, together = decoded(folder)
    alone = []
    for seg in segments(folder):
        alone += decoded(seg)[1]
    assert points(alone) == points(together)
    assert one_unit_per_name(points(alone)) == {}
    # what a segment starts with is in its metadata: Cn-02 from the segment after the one that read it
    states = [state_of(seg) for seg in segments(folder)]
    assert [all((s.get("") or {}).get(u, {}).get("holding") == CN02 for u in ("1", "2")) for s in states] == \
        [False, False, False, True, True, True]


def test_a_segment_starts_with_the_models_the_capture_had_identified(tmp_path, tmp_path_factory, capsys):
    """A byte capture says nothing of its units' models: they are identified from their answers.  Written
    again as segments, each later segment names them from its first frame, as the capture did there."""
    csv = simulated(tmp_path_factory, "a510.csv", "--scenario", "a510", "--duration", "8", "--seed", "2")
    folder = tmp_path / "cab"
    assert main(["replay", str(csv), "--baud", "19200", "--quiet", "--out", str(folder), "--rotate", "2s"]) == 0
    segs = sorted(folder.glob("*.mcap"))
    assert len(segs) >= 4
    _, together = decoded(folder)
    alone = [decoded(seg)[1] for seg in segs]
    assert points([f for frames in alone for f in frames]) == points(together)
    assert "generic" in {f.model for f in alone[0]}  # before the units were identified
    for frames in alone[1:]:
        assert {f.model for f in frames if f.unit} == {"a510"}
    assert {u: d["model"] for u, d in state_of(segs[-1])[""].items()} == {"1": "a510", "2": "a510"}


def test_a_folder_replayed_with_a_segment_missing_takes_up_the_next_ones_state(folder, tmp_path):
    kept = tmp_path / "kept"
    kept.mkdir()
    segs = segments(folder)
    for seg in segs[:2] + segs[3:]:  # the third (10-15 s), where the PLC first read Cn-02, is gone
        shutil.copy(seg, kept / seg.name)
    session_frames = decoded(kept)[1]  # no index: its files in name order
    hole = next(i for i, f in enumerate(session_frames) if any(a.code == "source.gap" for a in f.annotations))
    before, after = session_frames[:hole], session_frames[hole:]
    assert any(p.get("provisional") for f in before for p in f.points)
    assert not any(p.get("provisional") for f in after for p in f.points)
    assert any(p["name"] == "Output frequency" for f in after for p in f.points)
    assert one_unit_per_name(points(session_frames)) == {}


def test_a_trigger_on_the_scaled_name_fires_on_hz_and_its_window_replays_in_hz(whole, tmp_path, capsys):
    from sniffer.triggers import read_trigger

    rule = '"Output frequency" > 45'
    assert main(["replay", str(whole), "--quiet", "--trigger", rule, "--pre", "3s", "--post", "1s",
                 "--windows", str(tmp_path)]) == 0
    windows = sorted(tmp_path.glob("*.trigger-*.mcap"))
    assert windows
    for w in windows:
        meta = read_trigger(str(w))
        for firing in meta["firings"]:
            got = [p for p in firing["record"]["points"] if p["name"] == "Output frequency"]
            assert got and any(p["unit"] == "Hz" and p["value"] > 45 for p in got), firing["summary"]
        info, frames = decoded(w)  # alone, from its first frame, as the capture had it there
        assert info.extra[KEY][""]["1"]["holding"] == CN02
        assert frames and not any(p.get("provisional") for f in frames for p in f.points)


def test_a_dataset_of_segments_keeps_one_unit_per_name(folder, tmp_path, capsys):
    import pyarrow.parquet as pq

    from sniffer.dataset.layout import open_dataset
    from sniffer.dataset.query import connect

    ds = tmp_path / "fleet"
    assert main(["export", *map(str, segments(folder)), "--to", "dataset", str(ds)]) == 0  # each decoded alone
    con = connect(open_dataset(str(ds)))
    try:
        got = con.execute("SELECT name, eng_unit, count(*) FROM points WHERE name LIKE 'Output frequency%' "
                          "GROUP BY ALL ORDER BY ALL").fetchall()
    finally:
        con.close()
    _, together = decoded(folder)
    want = defaultdict(int)
    for _unit, name, eng, _v in points(together):
        if name.startswith("Output frequency"):
            want[(name, eng)] += 1
    assert got == sorted((name, eng, n) for (name, eng), n in want.items())
    assert {name for name, _, _ in got} == {"Output frequency", "Output frequency (% of Cn-02)"}
    # each file says what the decoders knew where its part began
    for f in sorted(ds.rglob("points/**/*.parquet")):
        state = json.loads(pq.read_schema(f).metadata[b"sniffer.decoder_state"])
        seq = int(f.stem.split("-")[-2])  # CAPTURE-SEQ-HASH: the segment it holds
        assert ((state.get("") or {}).get("1", {}).get("holding") == CN02) == (seq > 3)


def test_mqtt_and_foxglove_keep_a_provisional_value_on_a_topic_of_its_own(whole):
    from sniffer.formats.mcap.foxglove import Foxglove
    from sniffer.mqtt.bridge import Bridge
    from sniffer.mqtt.options import MqttSpec, parse_url

    info, frames = decoded(whole)
    bridge = Bridge(MqttSpec(**parse_url("mqtt://127.0.0.1/plant").__dict__), info)
    fox = Foxglove(info)
    mqtt, channels = defaultdict(set), defaultdict(set)
    for f in frames:
        for m in bridge.frame(f):
            if m.topic.startswith("plant/default/1/output_frequency"):
                d = json.loads(m.payload)
                mqtt[m.topic].add((d["unit"], d.get("provisional", False)))
        for topic, _t, data in fox.frame(f, f.t_ns):
            if topic.startswith("/values/u1/Output_frequency"):
                d = json.loads(data)
                channels[topic].add((d.get("unit"), d.get("provisional", False)))
    assert dict(mqtt) == {"plant/default/1/output_frequency": {("Hz", False)},
                          "plant/default/1/output_frequency_pct_of_cn_02": {("%", True)}}
    assert dict(channels) == {"/values/u1/Output_frequency": {("Hz", False)},
                              "/values/u1/Output_frequency_pct_of_Cn_02": {("%", True)}}
