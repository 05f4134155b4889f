"""`sniffer export CAPTURE --to FORMAT --out PATH`: a decoded capture as csv, parquet, pcap(ng), mcap or jsonl;
`sniffer export CAPTURE... --to dataset DIR`: captures into a fleet dataset (commands/dataset.py).

csv writes PATH (frames) and PATH's stem + '.points.csv'; parquet likewise with
'.points.parquet'.  Files are written under temporary names and renamed when
complete; an output that is also the input is refused; a Ctrl-C keeps what
was written so far (a valid, shorter file).
"""

from __future__ import annotations

from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.formats import FileSink
from sniffer.commands.common import UsageError, jobs_for, report, say
from sniffer.commands.replay import file_source


def cmd_export(spec: CaptureSpec, args) -> int:
    files = [*spec.inputs, *getattr(args, "more_files", ())]
    if args.to == "dataset":
        root = getattr(args, "dataset", None) or args.out
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
    if not args.out:
        raise UsageError(f"--to {args.to} needs --out PATH")
    if args.link:
        raise UsageError("--link is for --to dataset")
    spec = spec.with_(input=files[0], inputs=(files[0],))  # a folder of segments is one capture (segset.py)
    # checked before the input is read; written as it fills, never by the clock: the same bytes every time
    sink = FileSink(args.to, args.out, inputs=spec.read_paths(), timed_flush=False)
    source = file_source(spec)
    jobs = jobs_for(spec, args)
    if jobs > 1:
        from sniffer.commands.common import parallel_run, run_with_bar
        from sniffer.parallel.outputs import file_output

        run = parallel_run(spec, source, [file_output(sink)], jobs, spec.input if args.progress else None)
        run_with_bar(run)
        return _done(run, spec)
    session = Session(spec, source, [sink])
    bar = None
    if args.progress:
        from sniffer.capture.progress import ReplayProgress

        bar = ReplayProgress(spec.input, source=source, frames=lambda: session.frames_out)
        session.on_event = bar.update
    try:
        session.open()
        session.run()
    finally:
        if bar is not None:
            bar.close()
    return _done(session, spec)


def _done(session, spec: CaptureSpec) -> int:
    rc = report(session, label=spec.input)
    if rc == 0:
        say(f"wrote {', '.join(o.path for o in session.outputs)} ({session.frames_out} frames)")
    return rc
