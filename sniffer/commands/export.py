"""`sniffer export CAPTURE --to FORMAT --out PATH`: a decoded capture as csv, parquet, pcap(ng), mcap or jsonl;
`sniffer export CAPTURE... --to dataset DIR`: captures into a fleet dataset (commands/dataset.py).

csv writes PATH (frames) and PATH's stem + '.points.csv'; parquet likewise with
'.points.parquet'.  Files are written under temporary names and renamed when
complete; an output that is also the input is refused; a Ctrl-C keeps what
was written so far (a valid, shorter file).
"""

from __future__ import annotations

import argparse

from sniffer.capture.settings import CaptureSpec
from sniffer.formats import EXPORT_FORMATS, FileSink
from sniffer.commands.common import UsageError, jobs_for, report, say
from sniffer.commands.flags import command_parser, dataset_flags, foxglove_flags, input_format_flag, logic_flags
from sniffer.commands.replay import file_source
from sniffer.decoding import decode


class ExportTo(argparse.Action):
    """`--to FORMAT`, or `--to dataset DIR` (DIR may also be given as --out); files after DIR are inputs."""

    def __call__(self, parser, namespace, values, option_string=None):
        fmt, *rest = values
        if fmt not in (*EXPORT_FORMATS, "dataset"):
            raise UsageError(f"argument --to: invalid choice: {fmt[:40]!r} (choose from "
                             f"{', '.join(EXPORT_FORMATS)}, dataset)")
        namespace.to = fmt
        if fmt == "dataset" and rest:
            namespace.dataset, rest = rest[0], rest[1:]
        elif rest:
            raise UsageError(f"--to {fmt} takes no folder: give the file as --out PATH (and the captures before --to)")
        namespace.more_files = rest


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "export", help="decode a capture into csv, parquet, pcap (Wireshark), mcap or jsonl, or "
                                   "captures into a fleet dataset (--to dataset DIR)",
        description="""\
            Decode a capture into a file other tools read: csv and parquet (frames, plus PATH's stem
            .points.csv/.parquet with one row per register value), pcap for Wireshark, mcap (decoded again),
            jsonl; or take captures into a fleet dataset that `sniffer query` reads (docs/fleet.md).""",
        examples=["sniffer export cabinet3.mcap --to csv --out cabinet3.csv",
                  "sniffer export cabinet3.mcap --to pcap --out cabinet3.pcapng   # open in Wireshark",
                  "sniffer export line1/*.mcap line2/*.mcap --to dataset /srv/fleet"])
    p.add_argument("file", nargs="*", help="capture file: MCAP, byte CSV, Saleae CSV, pcap/pcapng (several with "
                                           "--to dataset: each is a segment of the dataset)")
    input_format_flag(p)
    p.add_argument("--to", required=True, nargs="+", action=ExportTo, metavar=("FORMAT", "DIR"),
                   help=f"output format: {', '.join(EXPORT_FORMATS)}, or `dataset DIR`: a partitioned Parquet "
                        "dataset in folder DIR (made if new, else appended to; docs/fleet.md)")
    p.add_argument("--out", metavar="PATH", help="output file (csv/parquet: also PATH stem.points.*); with --to "
                                                 "dataset: the dataset folder")
    dataset_flags(p, "a progress bar on stderr")
    logic_flags(p)
    foxglove_flags(p)


def run(spec: CaptureSpec, args) -> int:
    files = [*spec.inputs, *getattr(args, "more_files", ())]
    if args.to == "dataset":
        root = getattr(args, "dataset", None) or spec.out
        if not root:
            raise UsageError("--to dataset needs the dataset folder: --to dataset DIR")
        if not files:
            raise UsageError("export needs a capture file: sniffer export CAPTURE... --to dataset DIR")
        from sniffer.commands.dataset import export_dataset

        return export_dataset(spec, args, files, root)
    if len(files) != 1:
        raise UsageError(f"--to {args.to} writes one capture: give one file, or a rotated capture's folder "
                         f"(several files go into --to dataset DIR)"
                         if files else "export needs a capture file: sniffer export CAPTURE --to FORMAT --out PATH")
    if not spec.out:
        raise UsageError(f"--to {args.to} needs --out PATH")
    if args.link:
        raise UsageError("--link is for --to dataset")
    spec = spec.with_(input=files[0], inputs=(files[0],))  # a folder of segments is one capture (segset.py)
    # checked before the input is read; written as it fills, never by the clock: the same bytes every time
    sink = FileSink(args.to, spec.out, inputs=spec.read_paths(), timed_flush=False)
    session = decode(spec, file_source(spec), [sink], jobs=jobs_for(spec, args),
                     progress=spec.input if args.progress else None)
    session.open()
    session.run()
    return _done(session, spec)


def _done(session, spec: CaptureSpec) -> int:
    rc = report(session, label=spec.input)
    if rc == 0:
        say(f"wrote {', '.join(o.path for o in session.outputs)} ({session.frames_out} frames)")
    return rc
