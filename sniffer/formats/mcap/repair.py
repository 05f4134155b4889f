"""Repair an MCAP capture that was never finished (killed writer, full disk, damage).

Such a file has no summary or footer, so Foxglove and mcap's seeking reader
refuse it.  `repair` copies every complete record (header, schemas,
channels, metadata, attachments, messages) into a new, properly finished
file and reports what it kept.  Damage in the middle (a chunk failing its
CRC, a record that does not parse) loses only that record: the scan
(sniffer.formats.mcap.scan) finds the next intact one and every record after
the hole is kept too; the holes are reported.  It works on any MCAP file,
not only ours.
The output is written next to its final name and renamed into place, so an
interrupted repair never leaves a half-written file under that name.
"""

from __future__ import annotations

import os

from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from sniffer.formats.outputs import FILE_MODE
from sniffer.events import CaptureError
from sniffer.formats.mcap.scan import Hole, Scan, open_file


def default_output(src: str | os.PathLike[str]) -> str:
    """`capture.mcap` -> `capture.repaired.mcap`; a killed capture's `capture.mcap.part` -> `capture.mcap`
    (the name it would have had), unless that is taken."""
    src = os.fspath(src)
    if src.endswith(".part") and src[:-5].endswith(".mcap") and not os.path.lexists(src[:-5]):
        return src[:-5]
    if src.endswith(".part"):
        src = src[:-5]
    base, ext = os.path.splitext(src)
    return f"{base}.repaired{ext or '.mcap'}"


def repair(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> dict:
    """Write `dst`: a finished MCAP holding every complete record of `src`.

    Returns counts: messages (kept), topics ({topic: messages}), metadata,
    attachments, orphans (messages of an unknown channel, dropped),
    bytes_in, bytes_kept (the data section read), bytes_dropped (damaged
    holes and a cut-off tail), skipped ([(offset, bytes)] of each hole),
    was_finished, problem (everything that was lost, in one line, or None).
    Raises CaptureError if src is not MCAP, or src and dst are one file.
    """
    s, d = os.fspath(src), os.fspath(dst)
    if os.path.exists(d) and os.path.samefile(s, d):
        raise CaptureError(f"{s}: repair needs a different output file")
    fh, size, tail_ok = open_file(s)
    tmp = f"{d}.part"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0), FILE_MODE)
        with fh, open(fd, "wb") as out:
            counts = _copy(fh, size, tail_ok, out)
        os.replace(tmp, d)
    except OSError as e:
        _remove(tmp)
        raise CaptureError(f"{d}: cannot write repaired file: {e.strerror or e}") from None
    except BaseException:
        _remove(tmp)
        raise
    return counts


def _copy(fh, size: int, tail_ok: bool, out) -> dict:
    scan = Scan(fh, size, tail_ok=tail_ok)
    w = Writer(out, compression=CompressionType.ZSTD)
    schema_ids: dict[int, int] = {0: 0}
    channel_ids: dict[int, int] = {}
    topics: dict[str, int] = {}
    counts = {"messages": 0, "metadata": 0, "attachments": 0, "orphans": 0}
    started = False
    for rec in scan.records():
        if isinstance(rec, Hole):
            continue
        if isinstance(rec, Header):
            if not started:
                w.start(profile=rec.profile, library=rec.library)
                started = True
            continue
        if not started:  # the header was lost in damage
            w.start(profile="", library="sniffer repair")
            started = True
        if isinstance(rec, Schema):
            if rec.id not in schema_ids:  # other writers repeat schemas in every chunk
                schema_ids[rec.id] = w.register_schema(rec.name, rec.encoding, rec.data)
        elif isinstance(rec, Channel):
            if rec.id not in channel_ids and rec.schema_id in schema_ids:
                channel_ids[rec.id] = w.register_channel(
                    rec.topic, rec.message_encoding, schema_ids[rec.schema_id], dict(rec.metadata)
                )
        elif isinstance(rec, Message):
            cid = channel_ids.get(rec.channel_id)
            if cid is None:  # its definition was in damaged bytes: a finished file repeats it in its summary
                cid = _recover(scan, w, rec.channel_id, schema_ids, channel_ids)
            if cid is None:
                counts["orphans"] += 1
                continue
            w.add_message(cid, rec.log_time, rec.data, rec.publish_time, rec.sequence)
            topic = scan.channels[rec.channel_id].topic
            topics[topic] = topics.get(topic, 0) + 1
            counts["messages"] += 1
        elif isinstance(rec, Metadata):
            w.add_metadata(rec.name, dict(rec.metadata))
            counts["metadata"] += 1
        elif isinstance(rec, Attachment):
            w.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type, rec.data)
            counts["attachments"] += 1
    if not started:  # cut before the header was written: an empty but valid file
        w.start(profile="", library="sniffer repair")
    w.finish()
    skipped = [(off, n) for off, n, _why in scan.holes]
    holes = sum(n for _off, n in skipped)
    cut = 0 if scan.finished else size - scan.end
    problems = [f"{why}: {n} bytes skipped" for _off, n, why in scan.holes]
    if scan.problem and not scan.finished:
        problems.append(scan.problem)
    if counts["orphans"]:
        problems.append(f"{counts['orphans']} messages of channels lost in the damage dropped")
    return {
        **counts,
        "topics": topics,
        "bytes_in": size,
        "bytes_kept": scan.end - holes,
        "bytes_dropped": holes + cut,
        "skipped": skipped,
        "was_finished": tail_ok and scan.finished and not skipped,
        "problem": "; ".join(problems) or None,
    }


def _recover(scan: Scan, w: Writer, cid: int, schema_ids: dict, channel_ids: dict) -> int | None:
    ch = scan.lost_channel(cid)
    if ch is None:
        return None
    if ch.schema_id not in schema_ids:
        sc = scan.lost_schema(ch.schema_id)
        if sc is None:
            return None
        schema_ids[sc.id] = w.register_schema(sc.name, sc.encoding, sc.data)
    channel_ids[cid] = w.register_channel(ch.topic, ch.message_encoding, schema_ids[ch.schema_id], dict(ch.metadata))
    return channel_ids[cid]


def _remove(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass
