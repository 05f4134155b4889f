"""The rules every reader of a file or an address goes through, so a new input cannot forget them.

    fh = open_regular(path)                       # a regular file, or InputError: a FIFO, device, folder refused
    text = read_text(path, CAPS["golden"], "a golden file")      # bounded: the cap is named in the error
    with Archive(path, "a sigrok session file") as z:            # a zip: every member's size and ratio capped,
        data = z.read("metadata", MAX_META)                      # encryption and unknown methods refused
    x = finite(text, "--params x.csv: line 3: value")            # nan, inf, 1e400 refused
    addr = parse_address("tcp://host:8786", "--dask")            # checked before any connection
    first = probe(addr, "--dask", expect=...)                    # connect and reply timeouts

Every refusal is an InputError: one line, exit 2 (sniffer.cli).  tests/test_input_rules.py holds every file
and address argument of every command to these rules (its exceptions list says why each exception is one).
"""

from sniffer.inputs.address import Address, parse_address, probe
from sniffer.inputs.archive import Archive
from sniffer.inputs.errors import InputError
from sniffer.inputs.files import CAPS, not_regular, open_regular, read_capped, read_lines, read_text
from sniffer.inputs.numbers import finite

__all__ = ["Address", "Archive", "CAPS", "InputError", "finite", "not_regular", "open_regular",
           "parse_address", "probe", "read_capped", "read_lines", "read_text"]
