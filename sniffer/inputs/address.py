"""Network addresses: parsed and checked before any connection, then probed with a connect and a reply timeout.

    addr = parse_address("tcp://host:8786", "--dask", schemes=("tcp",), default_port=8786)
    first = probe(addr, "--dask", reply=8)   # the peer's first 8 bytes, or one line: refused, silent, closed

A library handed a malformed address raises what it likes (tracebacks), and one handed a port where
something else listens may wait for ever or take the first bytes of an HTTP answer for a length (an
allocation of exabytes).  So the command parses the address here, and reads the peer's first bytes
itself, bounded in time and size, before the library connects.
"""

from __future__ import annotations

import ipaddress
import re
import socket
from dataclasses import dataclass

from sniffer.inputs.errors import InputError

CONNECT_TIMEOUT_S = 5.0
REPLY_TIMEOUT_S = 5.0
_HOSTNAME = re.compile(r"(?=.{1,253}$)[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
                       r"(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*\.?")


def is_host(text: str) -> bool:
    """A host name, an IPv4 or an IPv6 address (without brackets): what any connecting option may name."""
    try:
        ipaddress.ip_address(text)
        return True
    except ValueError:
        return bool(_HOSTNAME.fullmatch(text))


@dataclass(frozen=True)
class Address:
    scheme: str
    host: str
    port: int

    def __str__(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.scheme}://{host}:{self.port}"


def parse_address(text: str, what: str, schemes: tuple[str, ...] = ("tcp",), default_port: int | None = None
                  ) -> Address:
    """`SCHEME://HOST:PORT` (or `HOST:PORT`, the first scheme) as an Address; InputError (one line) if not one."""
    shown = repr(str(text)[:80])
    hint = f"(e.g. {schemes[0]}://host:{default_port or 8786})"
    scheme, sep, rest = str(text).partition("://")
    if not sep:
        scheme, rest = schemes[0], str(text)
    if scheme not in schemes:
        raise InputError(f"{what} {shown}: scheme {scheme[:20]!r} is not {' or '.join(schemes)} {hint}")
    if rest.startswith("["):
        host, close, tail = rest[1:].partition("]")
        if not close:
            raise InputError(f"{what} {shown}: an IPv6 address without its closing ] {hint}")
        if tail and not tail.startswith(":"):
            raise InputError(f"{what} {shown}: {tail[:20]!r} after the address {hint}")
        port_text = tail[1:] if tail else None
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise InputError(f"{what} {shown}: {host[:40]!r} is not an IPv6 address {hint}") from None
    else:
        host, colon, port_text = rest.partition(":")
        port_text = port_text if colon else None
        if ":" in (port_text or ""):
            raise InputError(f"{what} {shown}: an IPv6 address goes in brackets, [::1]:8786 {hint}")
        if not host:
            raise InputError(f"{what} {shown}: no host {hint}")
        if not _HOSTNAME.fullmatch(host):
            raise InputError(f"{what} {shown}: {host[:40]!r} is not a host name or address {hint}")
    if port_text is None or port_text == "":
        if default_port is None:
            raise InputError(f"{what} {shown}: no port {hint}")
        return Address(scheme, host, default_port)
    if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise InputError(f"{what} {shown}: port {port_text[:20]!r} is not 1..65535 {hint}")
    return Address(scheme, host, int(port_text))


def probe(addr: Address, what: str, reply: int = 0, *, connect_timeout: float | None = None,
          reply_timeout: float | None = None) -> bytes:
    """Connect to `addr` within `connect_timeout`; with `reply` > 0, read the peer's first `reply` bytes within
    `reply_timeout` (a server that speaks first, as a Dask scheduler does).  InputError (one line) for a name
    that does not resolve, a refused or silent connect, a peer that says nothing or hangs up.  The timeouts:
    CONNECT_TIMEOUT_S and REPLY_TIMEOUT_S unless given."""
    connect_timeout = CONNECT_TIMEOUT_S if connect_timeout is None else connect_timeout
    reply_timeout = REPLY_TIMEOUT_S if reply_timeout is None else reply_timeout
    try:
        sock = socket.create_connection((addr.host, addr.port), timeout=connect_timeout)
    except socket.gaierror as e:
        raise InputError(f"{what} {addr}: unknown host ({e.strerror or e})") from None
    except TimeoutError:
        raise InputError(f"{what} {addr}: no connection within {connect_timeout:g} s") from None
    except OSError as e:
        raise InputError(f"{what} {addr}: cannot connect ({e.strerror or e})") from None
    try:
        sock.settimeout(reply_timeout)
        got = b""
        while len(got) < reply:
            try:
                data = sock.recv(reply - len(got))
            except TimeoutError:
                raise InputError(f"{what} {addr}: connected, but no answer within {reply_timeout:g} s "
                                 "(something else listens there?)") from None
            except OSError as e:
                raise InputError(f"{what} {addr}: the connection failed ({e.strerror or e})") from None
            if not data:
                raise InputError(f"{what} {addr}: connected, but it hung up without an answer") from None
            got += data
        return got
    finally:
        sock.close()
