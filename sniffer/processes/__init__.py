"""The processes of a live capture and the pipes between them: one place that owns that layout.

    sniffer live --tui:  the viewer (tui/run.py) -- socket --> the publisher (publisher.py)
                                                                  ^ pipe (publish_sink.py)
                         the capture (capture.py: `sniffer live --publish` as a child) <-- pipe -- the port's
                         reader (reader.py)
    stream.py     the viewers' stream on the socket;  attach.py  a viewer's side of it (`sniffer attach`)
    serve.py      `sniffer serve`: the TUI in browsers, one capture process
    pipes.py      length-prefixed messages between the processes;  parent_death.py  a child ends with its parent
    cpu_yield.py  the viewer and the publisher hand their CPU back while frames come in
"""

from sniffer import face

_EXPORTS = {
    "live_source": "sniffer.processes.reader",
    "CaptureProcess": "sniffer.processes.capture",
    "PublishSink": "sniffer.processes.publish_sink",
    "Attachment": "sniffer.processes.attach",
    "parse_address": "sniffer.processes.stream",
    "run_serve": "sniffer.processes.serve",
    "GiveWay": "sniffer.processes.cpu_yield",
}
__all__ = sorted(_EXPORTS)
__getattr__ = face(__name__, _EXPORTS)
