"""The codes each verdict counts, by the category they are declared with (decoders.registry.code_book).

A group asks "was this request retried?" as `not RETRY.isdisjoint(codes)`: what counts as a retry, a
timeout, a late answer, a UART error or a drive's fault is said where each code is declared, never here.
"""

from __future__ import annotations

from decoders.registry import code_book
from sniffer import codes

_BOOK = code_book()
UART = _BOOK.in_category(codes.UART_CAT)  # a byte received with a framing or parity error
RETRY = _BOOK.in_category(codes.RETRY_CAT)
UNANSWERED = _BOOK.in_category(codes.TIMEOUT_CAT)  # the request got no response
LATE = _BOOK.in_category(codes.LATE_CAT)
FAULT = _BOOK.in_category(codes.FAULT_CAT)
