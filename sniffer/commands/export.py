"""`sniffer export CAPTURE --to FORMAT --out PATH`: a decoded capture as csv, parquet, pcap(ng), mcap or jsonl.

csv writes PATH (frames) and PATH's stem + '.points.csv'; parquet likewise with
'.points.parquet'.  Files are written under temporary names and renamed when
complete; an output that is also the input is refused; a Ctrl-C keeps what
was written so far (a valid, shorter file).
"""

from __future__ import annotations

from ..session import Session
from ..settings import CaptureSpec
from ..sinks import FileSink
from .common import report, say
from .replay import file_source


def cmd_export(spec: CaptureSpec, args) -> int:
    sink = FileSink(args.to, args.out, inputs=spec.inputs or [spec.input])  # checked before the input is read
    source = file_source(spec)
    session = Session(spec, source, [sink])
    bar = None
    if args.progress:
        from ..progress import ReplayProgress

        bar = ReplayProgress(spec.input, source=source, frames=lambda: session.frames_out)
        session.on_event = bar.update
    try:
        session.open()
        session.run()
    finally:
        if bar is not None:
            bar.close()
    rc = report(session, label=spec.input)
    if rc == 0:
        say(f"wrote {', '.join(o.path for o in session.outputs)} ({session.frames_out} frames)")
    return rc
