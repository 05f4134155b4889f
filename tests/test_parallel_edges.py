"""`--jobs N` at the edges a field capture reaches: a line with no traffic at all, a file damaged all through,
damage outside the chunks the workers read.  Each gives what one process gives: the same output, the same
error line, the same exit status.  The captures are small (one part), so the coordinator decodes them in this
process and no worker is started."""

from __future__ import annotations

import struct

import pytest

from sniffer.cli import main

_RECORD = struct.Struct("<BQ")
CHUNK, CHANNEL, DATA_END = 0x06, 0x04, 0x0F


def _run(capfd, *args) -> tuple[int, str, str]:
    capfd.readouterr()
    rc = main([str(a) for a in args])
    out, err = capfd.readouterr()
    return rc, out, err


def _records(data: bytes):
    """(offset, opcode, length) of the data section's top-level records."""
    pos = 8
    while pos + 9 <= len(data):
        op, length = _RECORD.unpack_from(data, pos)
        yield pos, op, length
        if op == DATA_END:
            return
        pos += 9 + length


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    d = tmp_path_factory.mktemp("edges")
    quiet, small = d / "quiet.mcap", d / "small.mcap"
    assert main(["simulate", "--duration", "0.001", "--out", str(quiet)]) == 0  # the line says nothing
    assert main(["simulate", "--duration", "3", "--scenario", "errors", "--out", str(small)]) == 0
    good = small.read_bytes()
    chunks = bytearray(good)  # every chunk damaged in its middle: nothing in them reads
    for pos, op, length in _records(good):
        if op == CHUNK:
            chunks[pos + 9 + length // 2] ^= 0x55
    (d / "chunks.mcap").write_bytes(bytes(chunks))
    outside = bytearray(good)  # a channel record before the chunks that no longer parses; the chunks intact
    pos, _op, length = [r for r in _records(good) if r[1] == CHANNEL][-1]
    outside[pos + 9 + 2: pos + 9 + length] = b"\xff" * (length - 2)
    (d / "outside.mcap").write_bytes(bytes(outside))
    return d


COMMANDS = [("replay",), ("replay", "--format", "jsonl"), ("diagnose",), ("diagnose", "--format", "json")]


@pytest.mark.parametrize("name", ["quiet", "chunks", "outside"])
@pytest.mark.parametrize("command", COMMANDS, ids=[" ".join(c) for c in COMMANDS])
def test_jobs_gives_what_one_process_gives(capfd, captures, name, command):
    cap = captures / f"{name}.mcap"
    one = _run(capfd, command[0], cap, *command[1:], "--jobs", "1")
    assert one[0] in (0, 2) and "Traceback" not in one[2]
    assert _run(capfd, command[0], cap, *command[1:], "--jobs", "2") == one


@pytest.mark.parametrize("name", ["quiet", "chunks", "outside"])
def test_export_with_jobs_writes_what_one_process_writes(capfd, tmp_path, captures, name):
    cap = captures / f"{name}.mcap"
    one = _run(capfd, "export", cap, "--to", "csv", "--out", tmp_path / "one.csv", "--jobs", "1")
    two = _run(capfd, "export", cap, "--to", "csv", "--out", tmp_path / "two.csv", "--jobs", "2")
    assert two[0] == one[0] and two[2].replace("two.", "one.") == one[2]
    if one[0] == 0:
        assert (tmp_path / "two.csv").read_bytes() == (tmp_path / "one.csv").read_bytes()


def test_the_damaged_captures_are_damage_one_process_reports(capfd, captures):
    """The fixture's damage is what it means to be: one process reads the file and says so (exit 2)."""
    for name in ("chunks", "outside"):
        rc, _out, err = _run(capfd, "replay", captures / f"{name}.mcap", "--jobs", "1")
        assert rc == 2 and "damaged" in err, (name, err)


def test_only_an_intact_file_is_read_by_number(captures):
    """The workers read a finished file's chunks by number; damage outside them leaves the file to the reader."""
    from sniffer.formats.mcap.ranges import raw_index

    assert raw_index(str(captures / "small.mcap")) is not None
    assert raw_index(str(captures / "outside.mcap")) is None


def test_a_compact_segment_is_read_in_order_with_the_same_output(captures, tmp_path, capfd):
    """A rotated segment's /raw message holds a second of events (format 2): not numbered by event, so the
    workers do not read it by number; --jobs gives one process's output all the same."""
    from sniffer.formats.mcap.ranges import raw_index

    rc, _out, err = _run(capfd, "replay", captures / "small.mcap", "--quiet", "--rotate", "1h", "--out", tmp_path / "s")
    assert rc == 0, err
    (seg,) = (tmp_path / "s").glob("*.mcap")
    assert raw_index(str(seg)) is None
    one = _run(capfd, "replay", seg, "--format", "jsonl", "--jobs", "1")
    assert one == _run(capfd, "replay", seg, "--format", "jsonl", "--jobs", "2")
    whole = _run(capfd, "replay", captures / "small.mcap", "--format", "jsonl", "--jobs", "1")
    assert one[0] == 0 and one[1] == whole[1] and one[1].count("\n") > 10


@pytest.fixture(scope="module")
def killed_set(tmp_path_factory):
    """A rotated capture's folder with a segment that was not closed cleanly (its capture killed)."""
    d = tmp_path_factory.mktemp("killed") / "set"
    assert main(["simulate", "--duration", "12", "--rotate", "5s", "--out", str(d)]) == 0
    seg = sorted(d.glob("*.mcap"))[1]
    seg.write_bytes(seg.read_bytes()[: seg.stat().st_size // 2])
    return d, seg


@pytest.mark.parametrize("jobs", ["1", "2"])
@pytest.mark.parametrize("command", [("replay",), ("diagnose",), ("export", "--to", "csv", "--out", "{tmp}/x.csv"),
                                     ("report", "--out", "{tmp}/x.html")], ids=lambda c: c[0])
def test_a_segment_not_closed_cleanly_is_noted_by_every_command_that_reads_it(capfd, tmp_path, killed_set, command,
                                                                             jobs):
    folder, seg = killed_set
    args = [a.format(tmp=tmp_path) for a in command[1:]]
    rc, _out, err = _run(capfd, command[0], folder, *args, "--jobs", jobs)
    assert rc == 0 and f"{seg.name} was not closed cleanly" in err, err
