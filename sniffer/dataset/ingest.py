"""One capture file into the dataset: decoded by one Session into a DatasetSink, then moved into place.

    ds = create_dataset("fleet")
    known = Known(ds.manifest())
    result = take_in(ds, "line3.mcap", spec, known)      # Taken | Skipped | Failed

The sink writes under `_staging/CAPTURE.PID/` (readers skip `_` folders); only a capture read
whole is moved in: each file renamed into its partition, then the manifest entry written, then
the staging folder removed.  A damaged or unreadable capture, a full disk, Ctrl-C: the staging
folder is removed and the dataset is as it was (the capture is not listed, a later run takes it in).
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field

from sniffer.line import SettingsError
from sniffer.formats.outputs import shown
from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.dataset.sink import DatasetSink
from sniffer.events import CaptureError
from sniffer.dataset.layout import STAGING, Dataset, Known, capture_name, new_entry


@dataclass
class Taken:
    path: str
    entry: dict
    files: list = field(default_factory=list)

    def line(self) -> str:
        e = self.entry
        return (f"{shown(self.path)}: {e['frames']} frames, {e['points']} points, {e['annotations']} annotations "
                f"-> {e['capture']} ({', '.join(e['partitions']) or 'no partition'})")


@dataclass
class Skipped:
    path: str
    entry: dict

    def line(self) -> str:
        same = "" if self.entry.get("source") == os.path.abspath(self.path) else f" (as {self.entry.get('source')})"
        return f"{shown(self.path)}: already in the dataset as {self.entry['capture']}{same}: skipped"


@dataclass
class Failed:
    path: str
    why: str

    def line(self) -> str:
        return self.why


def take_in(ds: Dataset, path: str, spec: CaptureSpec, known: Known, *, link: str | None = None,
            on_event=None) -> Taken | Skipped | Failed:
    """Decode `path` into the dataset unless the manifest has it (see the module doc)."""
    from sniffer.sources.files import FileSource

    try:
        entry, sha = known.seen(path)
    except OSError as e:
        return Failed(path, f"{shown(path)}: {e.strerror or e}")
    if entry is not None:
        return Skipped(path, entry)
    capture = capture_name(path, sha)
    staging = ds.path(STAGING, f"{capture}.{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)  # a killed run of this process id's
    try:
        os.makedirs(staging)
        sink = DatasetSink(staging, capture, link=link, source=os.path.abspath(path))
        session = Session(spec.with_(input=path), FileSource(path, spec.input_format), [sink], on_event=on_event)
        try:
            session.open()
            session.run()
        except (CaptureError, SettingsError) as e:
            return Failed(path, str(e))
        why = _why_not(session, path)
        if why:
            return Failed(path, why)
        entry = new_entry(path, sha)
        entry.update(frames=sink.counts["frames"], points=sink.counts["points"],
                     annotations=sink.counts["annotations"], first_ns=sink.first_ns, last_ns=sink.last_ns,
                     settings=session.resolved.describe(), links=sorted({k[0] for k in sink.partitions}),
                     partitions=[f"link={k[0]}/date={k[1]}" for k in sink.partitions],
                     files=[rel for rel, _, _ in sink.written])
        _move_in(ds, staging, sink.written)
        ds.record(entry)
        known.add(entry)
        return Taken(path, entry, sink.written)
    except OSError as e:
        where = e.filename if isinstance(e.filename, str) else ds.root
        return Failed(path, f"{shown(path)}: cannot write the dataset: {shown(where)}: {e.strerror or e}")
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        try:
            os.rmdir(ds.path(STAGING))  # when no other sniffer is writing
        except OSError:
            pass


def _why_not(session: Session, path: str) -> str | None:
    """Why a capture that was read is not taken in (damage, an error), or None."""
    if session.damage:
        more = f" (and {len(session.damage) - 1} more)" if len(session.damage) > 1 else ""
        first = session.damage[0]
        where = "" if first.startswith(path) else f"{shown(path)}: "
        return (f"{where}input damaged: {first}{more}; not taken in (`sniffer repair` writes a clean copy "
                f"to take in)")
    if session.storage_error:  # a full disk, an I/O error: the dataset's side
        return f"{shown(path)}: cannot write the dataset: {session.error}"
    if session.error:
        return f"{shown(path)}: {session.error}" if not session.error.startswith(path) else session.error
    return None


def _move_in(ds: Dataset, staging: str, written) -> None:
    """Each staged file renamed into its partition folder (a file of the same capture there is replaced:
    a run killed before its manifest entry wrote the same content)."""
    for rel, _, _ in written:
        dest = ds.path(rel)
        os.makedirs(os.path.dirname(dest), exist_ok=True)
        os.replace(os.path.join(staging, rel), dest)
