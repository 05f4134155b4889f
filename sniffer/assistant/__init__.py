"""`sniffer mcp`: an AI assistant's read-only tools (the Model Context Protocol, over stdio).

    sources.py    what the command was given: captures, datasets, live sockets (nothing else is opened)
    captures.py   a capture's summary, findings, report figures, filtered frames, a register's history
    datasets.py   read-only SQL over a fleet dataset, bounded in rows and time
    live.py       a live capture's current view through its socket
    bounds.py     bus text cleaned and capped, answers bounded in count and bytes
    server.py     the tools (the official `mcp` SDK, the mcp extra)
"""

from sniffer import face

__all__ = ["Source", "build", "given"]
__getattr__ = face(__name__, {"Source": "sniffer.assistant.sources", "build": "sniffer.assistant.server",
                              "given": "sniffer.assistant.sources"})
