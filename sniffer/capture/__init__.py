"""A capture: settings resolved once, one session driving source -> pipeline -> sinks.

    settings.py   CaptureSpec (what the user asked) -> Resolved (what the capture runs with)
    session.py    Session: opens the source, resolves, runs the pipeline into the sinks, closes and renames
    pipeline.py   Pipeline: framer -> pairer -> decoders, one link;  links.py  several links on one timeline
    pairer.py     which frame is a request, which answers it
    busfile.py    the bus file (a line's settings, units, models, links)
    status.py     the status file of an unattended capture;  progress.py  a replay's progress bar
    summary.py    what a capture wrote, in words
"""

from sniffer import face

_EXPORTS = {
    "CaptureSpec": "sniffer.capture.settings",
    "Resolved": "sniffer.capture.settings",
    "Session": "sniffer.capture.session",
    "decode_capture": "sniffer.capture.session",
    "Pipeline": "sniffer.capture.pipeline",
    "LinkPipelines": "sniffer.capture.links",
    "Pairer": "sniffer.capture.pairer",
    "BusFile": "sniffer.capture.busfile",
    "load_bus_file": "sniffer.capture.busfile",
    "StatusSink": "sniffer.capture.status",
    "summary_line": "sniffer.capture.summary",
}
__all__ = sorted(_EXPORTS)
__getattr__ = face(__name__, _EXPORTS)
