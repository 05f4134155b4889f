"""One way to decode a capture: every offline command's run, in one process or by parts (entry.py).

    run = decode(spec, source, sinks, jobs=jobs, progress=label)     # a Run: Session or ParallelRun
    run = decode_file(path, spec)                                    # opened, over a capture file

    entry.py    decode, decode_file, the Run interface, the progress bar and the unfinished-file notes
"""

from sniffer import face

_EXPORTS = {
    "Run": "sniffer.decoding.entry",
    "UnfinishedNotes": "sniffer.decoding.entry",
    "decode": "sniffer.decoding.entry",
    "decode_file": "sniffer.decoding.entry",
    "note_unfinished": "sniffer.decoding.entry",
    "split_of": "sniffer.decoding.entry",
    "unfinished_paths": "sniffer.decoding.entry",
}
__all__ = sorted(_EXPORTS)
__getattr__ = face(__name__, _EXPORTS)
