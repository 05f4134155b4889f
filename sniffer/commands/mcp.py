"""`sniffer mcp [CAPTURE|FOLDER|DATASET|SOCKET]...`: read-only tools for an AI assistant, stdio (sniffer.assistant)."""

from __future__ import annotations

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK, UsageError
from sniffer.commands.flags import command_parser


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "mcp", help="read-only tools for an AI assistant (Model Context Protocol, stdio)",
        description="""\
            Serve read-only tools to an AI assistant over stdio (the Model Context Protocol): the summary and
            units of the captures given, diagnose's findings, frames by the filter language (paged), a register's
            history, the report's figures, SQL over a fleet dataset (read-only, bounded in rows and time) and a
            live capture's current view through its socket.  The assistant reads only what is named here; no
            tool writes to a bus or a file.  Its client starts this command: docs/mcp.md has the configuration
            for Claude Desktop, Claude Code, VS Code, Cursor and others.""",
        examples=["sniffer mcp cabinet3.mcap",
                  "sniffer mcp /var/lib/sniffer/cab3 fleet/ /run/sniffer/cab3.sock"])
    p.add_argument("sources", nargs="+", metavar="CAPTURE|FOLDER|DATASET|SOCKET",
                   help="capture files or rotated captures' folders, fleet datasets' folders, live captures' "
                        "sockets (--publish SOCKET, or tcp:HOST:PORT)")


def run(spec: CaptureSpec, args) -> int:
    from sniffer import need
    from sniffer.assistant import build, given

    need("mcp", "sniffer mcp")
    served = given(args.sources)  # a path that is none of them: one line, exit 2, before serving
    if not served:
        raise UsageError("sniffer mcp needs a capture, a dataset or a socket to serve")
    build(served).run("stdio")
    return EXIT_OK
