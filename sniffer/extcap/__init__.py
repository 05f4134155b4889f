"""Wireshark's extcap interface: `sniffer extcap` lists the lines it can capture as Wireshark interfaces and
captures one into Wireshark's pipe as pcapng (Modbus RTU, link type 147, a comment on every packet).

    interfaces.py  what is listed: serial adapters (/dev/serial/by-id), ports and bus files the launcher
                   names, sigrok analyzers; the DLT; the config dialog of each
    capture.py     --capture: the dialog's values into a `sniffer live ... --format pcapng` run on the fifo
    install.py     --install: the launcher in the user's personal extcap folder (`tshark -G folders`)

The protocol: https://www.wireshark.org/docs/wsdg_html_chunked/ChCaptureExtcap.html.  Passive as every
capture: the port is opened read-only by the same code `sniffer live` uses.
"""
