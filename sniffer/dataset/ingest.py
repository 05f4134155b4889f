"""One capture file into the dataset: decoded by one Session into a DatasetSink, then moved into place.

    ds = create_dataset("fleet")
    tidy(ds)                                             # what killed runs left: said, then removed
    known = Known(ds.manifest())
    result = take_in(ds, "line3.mcap", spec, known)      # Taken | Skipped | Failed

The sink writes under `_staging/CAPTURE.PID/` (readers skip `_` folders), holding a lock on its
`.lock` file while it works; only a capture read whole is moved in: each file renamed into its
partition, then the manifest entry written, then the staging folder removed.  A damaged or
unreadable capture, a full disk, Ctrl-C: the staging folder is removed and the dataset is as it
was (the capture is not listed, a later run takes it in).  A run killed outright leaves its
staging folder: the next run's `tidy` removes every one whose lock nobody holds.

Whole means closed cleanly: an MCAP without its end (still being copied or written, or its
capture killed) or a file that changed while it was read is not taken in (a later run takes it
when it is whole).  A file taken in before that changed since (the same path on this host, the
same first frame: the same capture, grown or rewritten) replaces its rows: the new files move in,
the new manifest entry names the old one in `replaces`, then the old files and entry are removed
(`tidy` finishes that if a run was killed in between).  Another capture at the same path (another
first frame) is added.
"""

from __future__ import annotations

import errno
import os
import shutil
import time
from dataclasses import dataclass, field

from sniffer.line import SettingsError
from sniffer.formats.outputs import lock_file, make_folders, shown
from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.dataset.sink import DatasetSink
from sniffer.events import CaptureError
from sniffer.dataset.layout import MANIFEST, STAGING, Dataset, Known, capture_name, new_entry, well_formed

LOCK = ".lock"  # in a staging folder: locked (flock) while its run is alive
ORPHAN_AGE_S = 60.0  # a staging folder without a lock file (an older sniffer's, or one killed as it began)


@dataclass
class Taken:
    path: str
    entry: dict
    files: list = field(default_factory=list)
    replaced: list = field(default_factory=list)  # the manifest entries of the file's earlier version

    def line(self) -> str:
        e = self.entry
        again = (f"; the file changed since it was taken in: its rows replace those of "
                 f"{', '.join(r['capture'] for r in self.replaced)}" if self.replaced else "")
        return (f"{shown(self.path)}: {e['frames']} frames, {e['points']} points, {e['annotations']} annotations "
                f"-> {e['capture']} ({', '.join(e['partitions']) or 'no partition'}){again}")


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
    got = prepare(ds, path, known)
    if not isinstance(got, Prepared):
        return got
    try:
        staged = stage(got.job(spec, link), on_event=on_event)
    except BaseException:  # Ctrl-C, a bug: nothing of the capture stays (commit's release otherwise)
        release(ds, got.staging, got.lock)
        raise
    return commit(ds, got, staged, known)


@dataclass
class Prepared:
    """A capture the dataset does not have yet, its staging folder made and locked by this process: `job()` is
    what decodes it (anywhere that sees the same files: a worker process, a Dask worker), `commit` takes it in."""

    path: str
    sha: str | None
    before: tuple
    capture: str
    staging: str
    lock: int

    def job(self, spec: CaptureSpec, link: str | None) -> dict:
        """What `stage` needs (plain data: it may run in another process or on another machine)."""
        return {"path": self.path, "staging": self.staging, "capture": self.capture, "spec": spec, "link": link}


def prepare(ds: Dataset, path: str, known: Known) -> Prepared | Skipped | Failed:
    """The first step of take_in: skipped if the manifest has the file; else its staging folder, locked."""
    try:
        before = _stat(path)
        entry, sha = known.seen(path)
    except OSError as e:
        return Failed(path, f"{shown(path)}: {e.strerror or e}")
    if entry is not None:
        return Skipped(path, entry)
    capture = capture_name(path, sha)
    staging = ds.path(STAGING, f"{capture}.{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)  # a killed run of this process id's
    try:
        make_folders(staging)
        return Prepared(path, sha, before, capture, staging, _hold(staging))
    except OSError as e:
        release(ds, staging, None)
        where = e.filename if isinstance(e.filename, str) else ds.root
        return Failed(path, f"{shown(path)}: cannot write the dataset: {shown(where)}: {e.strerror or e}")


def stage(job: dict, on_event=None) -> dict:
    """The second step: the capture decoded by one Session into its staging folder.  Plain data back: {"why":
    why it is not taken in} or what its manifest entry says ({"frames", ..., "written"})."""
    from sniffer.sources.files import FileSource

    path, spec = job["path"], job["spec"]
    try:
        sink = DatasetSink(job["staging"], job["capture"], link=job["link"], source=os.path.abspath(path))
        session = Session(spec.with_(input=path), FileSource(path, spec.input_format), [sink], on_event=on_event)
        try:
            session.open()
            if _unfinished(session):  # not whole: nothing decoded
                session.close()
                return {"why": f"{shown(path)}: {UNFINISHED}"}
            session.run()
        except (CaptureError, SettingsError) as e:
            return {"why": str(e)}
        why = _why_not(session, path)
        if why:
            return {"why": why}
        return {"frames": sink.counts["frames"], "points": sink.counts["points"],
                "annotations": sink.counts["annotations"], "first_ns": sink.first_ns, "last_ns": sink.last_ns,
                "settings": session.resolved.describe(), "links": sorted({k[0] for k in sink.partitions}),
                "partitions": [f"link={k[0]}/date={k[1]}" for k in sink.partitions],
                "files": [rel for rel, _, _ in sink.written], "written": list(sink.written)}
    except OSError as e:
        where = e.filename if isinstance(e.filename, str) else os.path.dirname(os.path.dirname(job["staging"]))
        return {"why": f"{shown(path)}: cannot write the dataset: {shown(where)}: {e.strerror or e}"}


def commit(ds: Dataset, p: Prepared, staged: dict, known: Known) -> Taken | Skipped | Failed:
    """The last step, in the order the captures were given: the staged files moved in and the manifest entry
    written (or the capture skipped, if one taken in since has the same content)."""
    path = p.path
    try:
        if "why" in staged:
            return Failed(path, staged["why"])
        why = _changed(path, p.before)
        if why:
            return Failed(path, why)
        entry = known.have(path, p.sha)  # an identical file taken in since this one was prepared
        if entry is not None:
            return Skipped(path, entry)
        entry = new_entry(path, p.sha)
        entry.update({k: v for k, v in staged.items() if k != "written"})
        old = known.earlier(entry)
        if old:
            entry["replaces"] = [e["capture"] for e in old]
        _move_in(ds, p.staging, staged["written"])
        ds.record(entry)
        for e in old:  # the new rows are in: the old go
            forget(ds, e)
        known.add(entry)
        known.drop(old)
        return Taken(path, entry, staged["written"], old)
    except OSError as e:
        where = e.filename if isinstance(e.filename, str) else ds.root
        return Failed(path, f"{shown(path)}: cannot write the dataset: {shown(where)}: {e.strerror or e}")
    finally:
        release(ds, p.staging, p.lock)


def release(ds: Dataset, staging: str, lock: int | None) -> None:
    shutil.rmtree(staging, ignore_errors=True)
    if lock is not None:
        os.close(lock)
    try:
        os.rmdir(ds.path(STAGING))  # when no other sniffer is writing
    except OSError:
        pass


UNFINISHED = ("not closed cleanly (still being copied or written, or its capture was killed): not taken in; a "
              "later run takes it in when it is whole (`sniffer repair` writes a whole copy of one that will not be)")


def _stat(path: str) -> tuple[int, int]:
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


def _unfinished(session: Session) -> bool:
    """An MCAP (or a segment of a folder) that does not end as a closed capture does."""
    return bool(getattr(session.source, "unfinished", None) or session.info.extra.get("mcap_unfinished"))


def _changed(path: str, before: tuple[int, int]) -> str | None:
    try:
        now = _stat(path)
    except OSError as e:
        return f"{shown(path)}: {e.strerror or e} after it was read: not taken in"
    if now != before:
        return (f"{shown(path)}: changed while it was read (still being copied or written?): not taken in; a later "
                "run takes it in")
    return None


def _hold(staging: str) -> int:
    """The staging folder's lock, held (flock) until the run ends: `tidy` leaves a folder whose lock is held."""
    fd = os.open(os.path.join(staging, LOCK), os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o600)
    if not lock_file(fd):  # a fresh folder of this run's own: nobody else knows it yet
        os.close(fd)
        raise OSError(errno.EAGAIN, "staging folder locked by another run", staging)
    return fd


def _abandoned(folder: str) -> bool:
    """A staging folder whose run is gone: its lock is free (or, without a lock file, an older sniffer's or
    one killed as it began: its process id is not running here and it is a minute old)."""
    try:
        fd = os.open(os.path.join(folder, LOCK), os.O_RDWR | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        pid = folder.rsplit(".", 1)[-1]
        try:
            old = time.time() - os.stat(folder).st_mtime > ORPHAN_AGE_S
        except OSError:
            return False
        return old and not (pid.isdigit() and _running(int(pid)))
    except OSError:
        return False
    try:
        return lock_file(fd)  # False: held, a run is writing it
    except OSError:
        return False
    finally:
        os.close(fd)


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def tidy(ds: Dataset) -> list[str]:
    """Remove what killed runs left (staging folders nobody holds; the old files of a capture another replaced
    when the run was killed before removing them); what was removed, one line each."""
    said = []
    folder = ds.path(STAGING)
    names = sorted(os.listdir(folder)) if os.path.isdir(folder) else []
    gone = [n for n in names if os.path.isdir(os.path.join(folder, n)) and _abandoned(os.path.join(folder, n))]
    for n in gone:
        shutil.rmtree(os.path.join(folder, n), ignore_errors=True)
    if gone:
        said.append(f"{shown(folder)}: removed {len(gone)} staging folder{'s' if len(gone) > 1 else ''} of killed "
                    f"runs ({', '.join(gone[:3])}{', ...' if len(gone) > 3 else ''})")
    try:
        os.rmdir(folder)
    except OSError:
        pass
    entries = [e for e in ds.manifest() if well_formed(e)]
    by_name = {e.get("capture"): e for e in entries}
    for e in entries:
        for name in e.get("replaces") or ():
            if isinstance(name, str) and name in by_name and name != e.get("capture"):
                forget(ds, by_name.pop(name))
                said.append(f"{shown(ds.root)}: removed {name}, replaced by {e.get('capture')} (a run was killed "
                            "before it removed it)")
    return said


def forget(ds: Dataset, entry: dict) -> None:
    """A capture's files and then its manifest entry removed (only files of its own name, inside the dataset)."""
    name = entry.get("capture")
    if not isinstance(name, str) or not name or "/" in name or name.startswith("."):
        return
    root = os.path.realpath(ds.root)
    files = entry.get("files")
    for rel in files if isinstance(files, list) else ():
        if not isinstance(rel, str) or os.path.basename(rel) != f"{name}.parquet":
            continue
        p = os.path.realpath(ds.path(rel))
        if p.startswith(root + os.sep) and not rel.startswith("_"):
            try:
                os.remove(p)
            except FileNotFoundError:
                pass
    try:
        os.remove(ds.path(MANIFEST, f"{name}.json"))
    except FileNotFoundError:
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
        make_folders(os.path.dirname(dest))
        os.replace(os.path.join(staging, rel), dest)
