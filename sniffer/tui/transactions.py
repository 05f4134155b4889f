"""Transactions: a request and its response, or what happened instead, as one entry.

Textual-free, fed by FrameStore as frames arrive (`add(row, frame, flags)`, O(1) a frame).  The
pipeline has paired the frames already: a request settles with `pair` set to its response's
index (the response follows it in capture order), or without one and an annotation saying why
(pair.timeout, pair.no_response, pair.end_of_capture), or as a broadcast that expects no answer;
a response without a request is an orphan.  So a transaction is opened by its request and
completed by its response, and every request and every response is in exactly one.

Per transaction the columns keep its rows (request, response: -1 none), its kind and its frames'
flags OR-ed; the text on screen is made from the frames for the rows shown only.  `view` is the
transactions whose request or response passes the frame filter, kept in step with the store's
view incrementally (`sync`): a filter applies to transactions as it does to frames.
"""

from __future__ import annotations

import bisect
from array import array

from sniffer import codes
from sniffer.frame import REQUEST, RESPONSE, Frame

OK, EXCEPTION, PENDING, TIMEOUT, NO_RESPONSE, END_OF_CAPTURE, BROADCAST, ORPHAN = range(8)
KIND_TEXT = {OK: "ok", EXCEPTION: "exception", PENDING: "awaiting its response", TIMEOUT: "timeout",
             NO_RESPONSE: "no response", END_OF_CAPTURE: "no response (capture ended)",
             BROADCAST: "broadcast (no answer expected)", ORPHAN: "no request"}
UNANSWERED = (TIMEOUT, NO_RESPONSE, END_OF_CAPTURE)


def _unanswered_kind(f: Frame) -> int:
    """Why a request has no response, from what the pairer annotated."""
    said = {a.code for a in f.annotations}
    if codes.TIMEOUT.code in said:
        return TIMEOUT
    if codes.END_OF_CAPTURE.code in said:
        return END_OF_CAPTURE
    return NO_RESPONSE


class Transactions:
    def __init__(self) -> None:
        self.req = array("q")  # request row, -1: none (an orphan response)
        self.rsp = array("q")  # response row, -1: none (yet)
        self.kind = array("B")
        self.flags = array("B")  # the store's frame flags of both frames, OR-ed
        self.tx_of_row = array("i")  # per store row: its transaction, -1: none (noise, unknown role)
        self._open: dict[int, int] = {}  # a request's Frame.index -> its transaction, until its response comes
        # the transactions shown: those with a frame in the store's view (ascending)
        self.view = array("q")
        self.view_of: object = None  # the store view object `view` was made from, and how much of it
        self._seen = 0

    def __len__(self) -> int:
        return len(self.kind)

    # ------------------------------------------------------------- intake
    def add(self, row: int, f: Frame, fl: int) -> None:
        """The store's row `row` holds frame `f` with flags `fl` (rows come in order)."""
        if f.role == REQUEST and f.unit is not None:
            tx = self._new(row, -1, fl)
            if f.pair is not None:
                self.kind.append(PENDING)
                self._open[f.index] = tx
            elif f.unit == 0:
                self.kind.append(BROADCAST)
            else:
                self.kind.append(_unanswered_kind(f))
        elif f.role == RESPONSE and f.unit is not None:
            tx = self._open.pop(f.pair, None) if f.pair is not None else None
            if tx is None:  # nothing pending, or its request came before this viewer joined
                tx = self._new(-1, row, fl)
                self.kind.append(ORPHAN)
            else:
                self.rsp[tx] = row
                self.flags[tx] |= fl
                self.kind[tx] = EXCEPTION if f.exception else OK
        else:
            tx = -1
        self.tx_of_row.append(tx)

    def _new(self, req: int, rsp: int, fl: int) -> int:
        self.req.append(req)
        self.rsp.append(rsp)
        self.flags.append(fl)
        return len(self.req) - 1

    # ------------------------------------------------------------- lookup
    def rows(self, tx: int) -> tuple[int, int]:
        return self.req[tx], self.rsp[tx]

    def first_row(self, tx: int) -> int:
        """The request's row, or the response's for an orphan."""
        r = self.req[tx]
        return r if r >= 0 else self.rsp[tx]

    # ------------------------------------------------------------- the filtered view
    def sync(self, store_view) -> bool:
        """Bring `view` up to the store's view (rows passing the frame filter, ascending).

        The store appends to its view as frames arrive and replaces it when the filter changes or
        a pause ends: new rows are mapped to their transactions, a new view object starts over.
        Returns whether `view` changed.
        """
        if store_view is not self.view_of:
            self.view_of, self._seen, self.view = store_view, 0, array("q")
        n = len(store_view)
        if n == self._seen:
            return False
        out, of_row = self.view, self.tx_of_row
        last = out[-1] if out else -1
        for r in store_view[self._seen:n]:
            t = of_row[r]
            if t > last:
                out.append(t)
                last = t
            elif 0 <= t < last:  # a response whose request was filtered out, after a later transaction
                i = bisect.bisect_left(out, t)
                if i == len(out) or out[i] != t:
                    out.insert(i, t)
        self._seen = n
        return True

    def nearest_pos(self, tx: int) -> int:
        """The position in `view` of a transaction, or of the next one shown (the last if none)."""
        return min(bisect.bisect_left(self.view, tx), max(len(self.view) - 1, 0))
