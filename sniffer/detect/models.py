"""Which drive model each unit of a detected line is, from the answers heard while listening.

The same identifier that names units during a capture (decoders/identify.py: evidence only that model
would give, never a guess from one register) reads the paired answers of the settled listen.  A unit it
cannot name yet stays unnamed: `detect` says which, and its bus file leaves them as comments, so that
uncommenting a line never takes a model's decoding away from a unit that was named.

    naming = Naming()
    naming.feed(evidence.answers)     # as many times as the listen grows; only new answers are read
    naming.named  -> {unit: Named(model, confidence, evidence)}
"""

from __future__ import annotations

from typing import NamedTuple


class Named(NamedTuple):
    model: str
    confidence: float
    evidence: str


NEW_EVIDENCE_S = 5.0  # a unit whose answers brought no new request this long (and 3 poll periods) says no more


class Naming:
    def __init__(self, model_files: list[str] | None = None) -> None:
        from decoders.registry import default_registry

        self._identifier = default_registry(model_files=list(model_files or ()) or None).identifier
        self._seen = 0  # answers of the current list already read
        self._list: list | None = None
        self._asked: dict[int, set[bytes]] = {}  # unit -> the requests (function, address, count) it answered
        self._news: dict[int, int] = {}  # unit -> when it last answered a request it had not answered before
        self._answers: dict[int, int] = {}
        self.named: dict[int, Named] = {}

    def feed(self, answers: list, protocol: str | None = None) -> dict[int, Named]:
        """Read the answers not read yet (the list of one listen; another list starts over)."""
        if answers is not self._list:
            self._list, self._seen = answers, 0
        own = _own_model(protocol)
        for f in answers[self._seen:]:
            self._answers[f.unit] = self._answers.get(f.unit, 0) + 1
            asked = self._asked.setdefault(f.unit, set())
            key = f.peer.adu[1:6] if f.peer is not None else b""
            if key not in asked:
                asked.add(key)
                self._news[f.unit] = f.t_ns
            if own is not None:
                self.named[f.unit] = Named(own, 1.0, f"the {protocol} protocol is the {own}'s own")
                continue
            got = self._identifier.observe(f) if self._identifier is not None else None
            if got is None:
                continue
            if got.model is None:  # an earlier guess withdrawn
                self.named.pop(f.unit, None)
            else:
                self.named[f.unit] = Named(got.model, got.confidence, got.evidence)
        self._seen = len(answers)
        return self.named

    def unnamed(self, units) -> list[int]:
        """The units seen (UnitSeen) that have no model yet (broadcasts, to unit 0, are no unit's)."""
        return [u.unit for u in units if u.unit and u.unit not in self.named]

    def wants_more(self, ev) -> bool:
        """Listen on? (`listen(..., more=naming.wants_more)`): a unit polled is not named yet and its answers
        may still tell: it answers, and lately to requests it had not answered before (a PLC that cycles
        through the same polls gives the identifier nothing new after a few cycles)."""
        if ev.best is None:
            return False
        self.feed(ev.answers, ev.best.protocol)
        now = ev.answers[-1].t_ns if ev.answers else 0
        from decoders.identify import SETTLED

        for u in ev.units:
            if not u.unit or u.unit in self.named or u.unit not in self._news:
                continue
            quiet_ns = max(NEW_EVIDENCE_S, 3 * (u.period_s or 0.0)) * 1e9
            if self._answers[u.unit] < SETTLED and now - self._news[u.unit] < quiet_ns:
                return True
        return False


def _own_model(protocol: str | None) -> str | None:
    """The model a protocol belongs to (the PD-series protocol is its drives' own), or None (Modbus: any)."""
    if protocol is None:
        return None
    from sniffer.protocols import get

    model = get(protocol).default_model
    return None if model == "generic" else model
