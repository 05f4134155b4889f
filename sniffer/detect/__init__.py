"""`sniffer detect PORT`: the line's baud rate, character format and protocol, found by listening only.

    candidates.py  the baud rates, formats and protocols tried
    window.py      one listen at one setting: the bytes, the tty's error marks, every protocol's framer
    evidence.py    what a listen says: frames that fit, pairs, UART errors, timing; fits / certain
    units.py       the units polled and their poll periods
    search.py      the order of the listens, when one has heard enough, the verdict
    listen.py      the port (read-only, as `live` opens it) set to each candidate in turn
    report.py      the ranked table, the units seen, the bus file
    hint.py        what a capture whose frames are mostly bad says to do: detect on its port, what it tries first
"""
