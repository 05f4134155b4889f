"""The dataset folder: dataset.json, partition paths, the manifest, a capture's name and link.

A capture segment is named `STEM-HASH` (its file's stem, made safe, and the first 12 hex
digits of its content's SHA-256): the same name in every table, and its manifest entry
`_manifest/STEM-HASH.json`.  A file is taken in once: one whose path, size and mtime a
manifest entry lists is skipped without being read, and one whose content hash is known
(a copy, a renamed file) after hashing.  An entry names the host that took the file in, so
`Known.earlier` finds an earlier version of a file by its path on this host only.  Entries are
separate files, written last, so sniffers appending at once never rewrite each other's work.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import re
import socket
import time
from dataclasses import dataclass

from sniffer import __version__
from sniffer.formats.outputs import FILE_MODE, make_folders, shown
from sniffer.formats.schemas import DATASET_TABLES, PARTITIONS, SCHEMA_VERSION, dataset_schemas, described
from sniffer.events import CaptureError
from sniffer.inputs import open_regular

FORMAT = "sniffer-dataset"
META = "dataset.json"
MANIFEST = "_manifest"
STAGING = "_staging"
DEFAULT_LINK = "default"
NO_CLOCK_DATE = "1970-01-01"  # a capture that does not know the wall clock (simulated): dated from the epoch
_UNSAFE = re.compile(r"[^\w.+-]")


class DatasetError(CaptureError):
    """A dataset folder that cannot be used: one line, exit code 2."""


def safe_name(text: str) -> str:
    """A name for a folder or file: letters, digits, `.`, `_`, `+`, `-` (anything else becomes `_`)."""
    name = _UNSAFE.sub("_", text.strip()).lstrip(".") or "_"
    return name[:80]


def link_name(info, given: str | None = None) -> str:
    """The link of a one-line capture: `--link NAME`, else the capture's port (`ttyUSB0`, as
    sniffer.capture.links names a port's link), else "default" (a simulated line, a file without a port)."""
    if given:
        return safe_name(given)
    port = (getattr(info, "port", "") or "").rstrip("/")
    if port.startswith("/") and not port.startswith("/dev/pts/"):
        return safe_name(os.path.basename(port))
    return DEFAULT_LINK


def date_of(wall_ns: int) -> str:
    """The UTC date of a wall-clock time in Unix ns ("2026-11-25")."""
    return dt.datetime.fromtimestamp(wall_ns // 1_000_000_000, dt.UTC).date().isoformat()


def day_bounds(wall_ns: int) -> tuple[int, int]:
    """[start, end) in Unix ns of the UTC day holding `wall_ns`."""
    day = 86_400 * 1_000_000_000
    start = wall_ns - wall_ns % day
    return start, start + day


def partition(table: str, link: str, date: str) -> str:
    """`frames/link=drives/date=2026-11-25` (relative to the dataset folder)."""
    return os.path.join(table, f"{PARTITIONS[0]}={link}", f"{PARTITIONS[1]}={date}")


def content_hash(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def capture_name(path: str, sha256: str) -> str:
    from sniffer.formats import stem_of

    return f"{safe_name(stem_of(path))}-{sha256[:12]}"


def _write_json(path: str, doc: dict, *, exclusive: bool = False) -> bool:
    """Write `doc` under a temporary name and rename (or link, when `exclusive`: False if `path` exists)."""
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, FILE_MODE), "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=1)
        fh.write("\n")
    try:
        if not exclusive:
            os.replace(tmp, path)
            return True
        try:
            os.link(tmp, path)
        except FileExistsError:
            return False
        return True
    finally:
        if exclusive and os.path.exists(tmp):
            os.remove(tmp)


def describe() -> dict:
    """dataset.json: what a reader needs to know before opening a file."""
    return {
        "format": FORMAT, "schema_version": SCHEMA_VERSION, "partitioning": list(PARTITIONS), "partition_style": "hive",
        "tables": {name: {"path": f"{name}/{PARTITIONS[0]}=*/{PARTITIONS[1]}=*/*.parquet", "columns": described(s)}
                   for name, s in dataset_schemas().items()},
        "created_by": f"sniffer {__version__}",
        "notes": "one file per capture segment, table and partition; appended, never rewritten; date is UTC "
                 f"({NO_CLOCK_DATE}: the capture did not know the wall clock); _manifest lists the captures",
    }


@dataclass
class Dataset:
    """An existing dataset folder (`open_dataset`) or a new one (`create_dataset`)."""

    root: str
    meta: dict

    def path(self, *parts: str) -> str:
        return os.path.join(self.root, *parts)

    def manifest(self) -> list[dict]:
        """Every capture taken in (their manifest entries; unreadable ones are left out)."""
        folder = self.path(MANIFEST)
        entries = []
        for name in sorted(os.listdir(folder)) if os.path.isdir(folder) else ():
            if name.endswith(".json"):
                try:
                    with open(os.path.join(folder, name), encoding="utf-8") as fh:
                        e = json.load(fh)
                except (OSError, ValueError, RecursionError):
                    continue
                if isinstance(e, dict):
                    entries.append(e)
        return entries

    def record(self, entry: dict) -> None:
        """The capture's manifest entry, written last (the capture counts as taken in from then on)."""
        make_folders(self.path(MANIFEST))
        _write_json(self.path(MANIFEST, entry["capture"] + ".json"), entry)


def open_dataset(root: str) -> Dataset:
    """A dataset folder made by the sniffer, of a schema version this sniffer reads; DatasetError otherwise."""
    meta_path = os.path.join(root, META)
    if not os.path.isdir(root):
        raise DatasetError(f"{shown(root)}: no such dataset folder")
    try:
        with open_regular(meta_path) as fh:  # a FIFO is refused, not waited on
            meta = json.loads(fh.read(1 << 20))  # a dataset.json is a few kB
    except CaptureError as e:
        if not os.path.lexists(meta_path):
            raise DatasetError(f"{shown(root)}: not a sniffer dataset (no {META}; "
                               f"`sniffer export CAPTURE --to dataset {shown(root)}` makes one)") from None
        raise DatasetError(f"{shown(meta_path)}: cannot be read: {str(e).removeprefix(meta_path + ': ')}") from None
    except FileNotFoundError:
        raise DatasetError(f"{shown(root)}: not a sniffer dataset (no {META}; "
                           f"`sniffer export CAPTURE --to dataset {shown(root)}` makes one)") from None
    except (OSError, ValueError, RecursionError) as e:
        why = "nested too deep" if isinstance(e, RecursionError) else getattr(e, "strerror", None) or str(e)[:200]
        raise DatasetError(f"{shown(meta_path)}: cannot be read: {why}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise DatasetError(f"{shown(meta_path)}: not a sniffer dataset description")
    version = meta.get("schema_version")
    if not isinstance(version, int) or version > SCHEMA_VERSION:
        raise DatasetError(f"{shown(root)}: schema version {version} is newer than this sniffer's "
                           f"({SCHEMA_VERSION}): update the sniffer")
    return Dataset(root, meta)


def create_dataset(root: str) -> Dataset:
    """The dataset at `root`, made when it is not there (a folder that holds other things is refused)."""
    if os.path.exists(os.path.join(root, META)):
        return open_dataset(root)
    parent = os.path.dirname(os.path.abspath(root))
    if not os.path.isdir(parent):
        raise DatasetError(f"{shown(root)}: folder {shown(parent)} does not exist")
    if os.path.exists(root) and not os.path.isdir(root):
        raise DatasetError(f"{shown(root)}: is a file, not a dataset folder")
    if os.path.isdir(root) and any(n not in (*DATASET_TABLES, MANIFEST, STAGING) for n in os.listdir(root)):
        raise DatasetError(f"{shown(root)}: folder holds other files and no {META}: not making a dataset there")
    try:
        make_folders(root)
        _write_json(os.path.join(root, META), describe(), exclusive=True)  # another sniffer may just have
    except OSError as e:
        raise DatasetError(f"{shown(root)}: cannot write: {e.strerror or e}") from None
    return open_dataset(root)


class Known:
    """What the manifest says was taken in: by (path, size, mtime) and by content hash."""

    def __init__(self, entries: list[dict]) -> None:
        self.entries = [e for e in entries if well_formed(e)]  # one edited by hand into other kinds: left out
        self.by_stat = {(e.get("source"), e.get("size"), e.get("mtime_ns")): e for e in self.entries}
        self.by_hash = {e.get("sha256"): e for e in self.entries}

    @staticmethod
    def stat_key(path: str) -> tuple:
        st = os.stat(path)
        return os.path.abspath(path), st.st_size, st.st_mtime_ns

    def seen(self, path: str) -> tuple[dict | None, str | None]:
        """(the manifest entry that has this file, or None; its content hash when it had to be computed)."""
        e = self.by_stat.get(self.stat_key(path))
        if e is not None:
            return e, None
        sha = content_hash(path)
        return self.by_hash.get(sha), sha

    def have(self, path: str, sha: str | None) -> dict | None:
        """`seen(path)` again, with the content hash `seen` gave (None: it found the file by its stat)."""
        e = self.by_stat.get(self.stat_key(path))
        return e if e is not None or sha is None else self.by_hash.get(sha)

    def add(self, entry: dict) -> None:
        self.entries.append(entry)
        self.by_stat[(entry["source"], entry["size"], entry["mtime_ns"])] = entry
        self.by_hash[entry["sha256"]] = entry

    def earlier(self, entry: dict) -> list[dict]:
        """The entries of an earlier version of `entry`'s file: the same path on the same host and the same
        first frame (the same capture, grown or rewritten; either without a wall clock: the path decides)."""
        def same(e: dict) -> bool:
            first = (e.get("first_ns"), entry.get("first_ns"))
            return (e.get("source") == entry["source"] and e.get("host", entry["host"]) == entry["host"]
                    and e.get("capture") != entry["capture"] and (None in first or first[0] == first[1]))
        return [e for e in self.entries if same(e)]

    def drop(self, entries: list[dict]) -> None:
        gone = {id(e) for e in entries}
        self.entries = [e for e in self.entries if id(e) not in gone]
        self.by_stat = {k: e for k, e in self.by_stat.items() if id(e) not in gone}
        self.by_hash = {k: e for k, e in self.by_hash.items() if id(e) not in gone}


# the manifest fields a run reads, and their kinds (an entry with another kind is left out, as an unreadable one)
_ENTRY_KINDS = {"capture": str, "source": str, "size": int, "mtime_ns": int, "sha256": str}


def well_formed(e) -> bool:
    """A manifest entry whose fields `Known` and `tidy` read are of the kinds this sniffer writes."""
    return (isinstance(e, dict) and all(isinstance(e.get(k), t) and not isinstance(e.get(k), bool)
                                        for k, t in _ENTRY_KINDS.items())
            and isinstance(e.get("host", ""), str) and isinstance(e.get("replaces", []), list)
            and isinstance(e.get("files", []), list) and isinstance(e.get("first_ns"), (int, type(None))))


def new_entry(path: str, sha256: str) -> dict:
    source, size, mtime_ns = Known.stat_key(path)
    return {"capture": capture_name(path, sha256), "source": source, "host": socket.gethostname(), "size": size,
            "mtime_ns": mtime_ns, "sha256": sha256, "schema_version": SCHEMA_VERSION, "sniffer_version": __version__,
            "ingested_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
