"""Live sources of timestamped bytes: serial ports (one, several links, a --tap), read-only.

    serial_port.py   opening a port read-only and setting its line: the one place that touches termios
    serial_live.py   SerialSource: one port's reader thread, stamping reads;  serial_links.py  several ports
    parmrk.py        UART errors marked in band by the tty;  pty_settings.py  what a pty keeps of a line
    lowlatency.py    the adapter's latency timer;  reader_priority.py  the reader thread's real-time priority

    files.py         FileSource: any capture file as events (its format's reader from sniffer.formats)
    segset.py        several capture files as one (a rotated capture's folder)
    sigrok_cli.py    a logic analyzer (live or a .sr file) through sigrok-cli: sigrok_uart.py, srzip.py,
                     logic_options.py, driver_enable.py

The process that runs the port readers for `sniffer live` is sniffer/processes/reader.py.
"""

from sniffer import face

_EXPORTS = {
    "SerialSource": "sniffer.sources.serial_live",
    "LinksSource": "sniffer.sources.serial_links",
    "PortLostError": "sniffer.sources.serial_live",
    "open_read_only": "sniffer.sources.serial_port",
    "FileSource": "sniffer.sources.files",
    "capture_source": "sniffer.sources.segset",
}
__all__ = sorted(_EXPORTS)
__getattr__ = face(__name__, _EXPORTS)
