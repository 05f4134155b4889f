"""`sniffer ingest FOLDER --to DIR`: a folder of MCAP captures into a fleet dataset (commands/dataset.py)."""

from __future__ import annotations

import os

from sniffer import need
from sniffer.formats.outputs import shown
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK, UsageError, say
from sniffer.commands.dataset import take_in_all
from sniffer.dataset.layout import create_dataset
from sniffer.commands.flags import command_parser, dataset_flags


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "ingest", help="take a folder of MCAP captures into a fleet dataset; already taken ones "
                                   "are skipped (docs/fleet.md)",
        description="""\
            Take every MCAP capture under FOLDER (subfolders too) into a fleet dataset, each whole or not at
            all; a capture the dataset has already is skipped, so a cron job can run it again and again.
            `sniffer query DIR` reads the dataset.""",
        examples=["sniffer ingest /var/lib/sniffer --to /srv/fleet",
                  "sniffer ingest /mnt/usb/site3 --to /srv/fleet --link site3 --progress"])
    p.add_argument("folder", help="the folder of captures (*.mcap, in subfolders too; *.part files are left out)")
    p.add_argument("--to", required=True, metavar="DIR", dest="dataset", help="the dataset folder (made if new)")
    dataset_flags(p, "a progress bar per capture on stderr")
    from sniffer.parallel.options import add_dask_flag

    add_dask_flag(p)


def run(spec: CaptureSpec, args) -> int:
    need("fleet", "sniffer ingest")
    folder = args.folder
    if not os.path.isdir(folder):
        raise UsageError(f"{shown(folder)}: no such folder" if not os.path.exists(folder) else
                         f"{shown(folder)}: not a folder (sniffer export FILE --to dataset DIR takes files)")
    root = os.path.abspath(args.dataset)
    files = []
    for here, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if os.path.abspath(os.path.join(here, d)) != root)  # not the dataset
        files += [os.path.join(here, n) for n in sorted(names) if n.endswith(".mcap")]
    if not files:
        create_dataset(args.dataset)
        say(f"no MCAP files in {shown(folder)}")
        return EXIT_OK
    return take_in_all(spec, args, files, args.dataset)
