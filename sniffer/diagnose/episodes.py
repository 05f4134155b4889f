"""When a finding happened: its episodes (from, to, how often), judged in windows of capture time.

    w = Windows()                       # one per thing counted (a link's damaged frames, a unit's strays)
    w.add(t_ns, hit)                    # every chance (a frame), hit or not; bounded memory
    w.episodes(d.seconds, "damaged frames")   # [Episode(from_s, to_s, count, what)]

A cause that is there all along gives one episode over the capture; one that comes and goes gives one
episode per time it came.  Which it is, the counts say: hits spread over the windows as a steady rate
spreads them (a dispersion test: the windows' counts against a Poisson of one rate) are one episode; hits
bunched in some windows are episodes where the windows' counts are far above the rate of the quiet
ones (a Poisson tail under 1e-3), windows one apart joined.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

MAX_WINDOWS = 512  # windows double in width as the capture grows past this many
MAX_EPISODES = 6  # named per finding (the first three and the last three); the count says how many in all
HOT_P = 1e-3
OVERDISPERSED_Z = 3.0


@dataclass(frozen=True)
class Episode:
    from_s: float
    to_s: float
    count: int  # how many times it showed in the episode (what `what` counts)
    what: str = ""  # "damaged frames", "requests unanswered", a fault's name ...
    chances: int = 0  # what was counted in the episode, hit or not (0: not known)

    def to_dict(self) -> dict:
        return {"from_s": round(self.from_s, 3), "to_s": round(self.to_s, 3), "count": self.count, "what": self.what}

    def words(self) -> str:
        what = f" ({self.count} {self.what})" if self.what else f" ({self.count}x)"
        return f"{self.from_s:.1f}-{self.to_s:.1f} s{what}"


def words(episodes: list[Episode], total: int | None = None) -> str:
    """'2 episodes: 20.1-60.0 s (120 requests unanswered), 90.0-95.2 s (31 requests unanswered)';
    `total` episodes in all when more happened than are listed."""
    n = max(total or 0, len(episodes))
    if not episodes:
        return ""
    head = f"{n} episode{'s' * (n != 1)}"
    shown = ", ".join(e.words() for e in episodes)
    more = f" ({len(episodes)} of {n} shown, the rest in --format json)" if n > len(episodes) else ""
    return f"{head}: {shown}{more}"


def merged(episodes: list[Episode]) -> list[Episode]:
    """Episodes of several counts of one cause (a unit's refused requests of each kind) as one list: those that
    overlap in time are one, their counts added."""
    out: list[Episode] = []
    for e in sorted(episodes, key=lambda e: e.from_s):
        if out and e.from_s <= out[-1].to_s:
            p = out[-1]
            out[-1] = Episode(p.from_s, max(p.to_s, e.to_s), p.count + e.count, p.what, p.chances + e.chances)
        else:
            out.append(e)
    return out


def keep(episodes: list, limit: int = MAX_EPISODES) -> list:
    """The first and the last ones of a long list (what a finding names)."""
    if len(episodes) <= limit:
        return list(episodes)
    return list(episodes[: limit // 2]) + list(episodes[-(limit - limit // 2):])


class Windows:
    """Chances and hits per window of capture time (bounded: windows double in width as time goes on)."""

    __slots__ = ("width", "t0", "n", "hits")

    def __init__(self, width_ns: int = 1_000_000_000) -> None:
        self.width = width_ns
        self.t0: int | None = None
        self.n: dict[int, int] = {}
        self.hits: dict[int, int] = {}

    def add(self, t_ns: int, hit: bool = False) -> None:
        if self.t0 is None:
            self.t0 = t_ns
        k = (t_ns - self.t0) // self.width
        if k >= MAX_WINDOWS:
            self._coarser()
            k = (t_ns - self.t0) // self.width
        n = self.n
        n[k] = n.get(k, 0) + 1
        if hit:
            self.hits[k] = self.hits.get(k, 0) + 1

    def mark(self, t_ns: int) -> None:
        """A hit on a chance counted already (add): an answer to a broadcast counted when the broadcast went."""
        if self.t0 is None:
            self.add(t_ns, True)
            return
        k = (t_ns - self.t0) // self.width
        if k >= MAX_WINDOWS:
            self._coarser()
            k = (t_ns - self.t0) // self.width
        self.n[k] = max(self.n.get(k, 0), self.hits.get(k, 0) + 1)
        self.hits[k] = self.hits.get(k, 0) + 1

    def _coarser(self) -> None:
        while (self.n and max(self.n) // 2 >= MAX_WINDOWS // 2) or not self.n:
            n: dict[int, int] = {}
            h: dict[int, int] = {}
            for k, v in self.n.items():
                n[k // 2] = n.get(k // 2, 0) + v
            for k, v in self.hits.items():
                h[k // 2] = h.get(k // 2, 0) + v
            self.n, self.hits = n, h
            self.width *= 2
            if not self.n:
                break

    @property
    def total_hits(self) -> int:
        return sum(self.hits.values())

    def episodes(self, seconds, what: str = "", min_hits: int = 3, join: int = 2) -> list[Episode]:
        """The episodes of the hits (see the module doc); `seconds(t_ns)` turns capture time into seconds
        from its start; hot windows `join` apart or less are one episode (a sparse cause leaves quiet windows
        inside its episode)."""
        hits_total = self.total_hits
        if hits_total == 0 or self.t0 is None:
            return []
        keys = sorted(self.n)
        span = (keys[0], keys[-1])
        if not self._bunched(keys, hits_total):
            return [self._episode(seconds, span[0], span[1], hits_total, what)]
        rate = hits_total / sum(self.n.values())
        quiet = [k for k in keys if self.hits.get(k, 0) <= self.n[k] * rate]
        base = sum(self.hits.get(k, 0) for k in quiet) / max(sum(self.n[k] for k in quiet), 1)
        hot = [k for k in keys if self._hot(self.hits.get(k, 0), self.n[k], base)]
        runs: list[list[int]] = []
        for k in hot:
            if runs and k - runs[-1][1] <= join:  # quiet windows between: the same episode
                runs[-1][1] = k
            else:
                runs.append([k, k])
        out = []
        for a, b in runs:
            count = sum(self.hits.get(k, 0) for k in range(a, b + 1))
            if count >= min_hits:
                out.append(self._episode(seconds, a, b, count, what))
        return out or [self._episode(seconds, span[0], span[1], hits_total, what)]

    def _bunched(self, keys: list[int], hits_total: int) -> bool:
        """Whether the windows' hits are overdispersed against one steady rate (index of dispersion)."""
        if len(keys) < 4:
            return False
        total = sum(self.n[k] for k in keys)
        rate = hits_total / total
        d = 0.0
        for k in keys:
            e = self.n[k] * rate
            d += (self.hits.get(k, 0) - e) ** 2 / max(e * (1 - rate), 1e-12)
        df = len(keys) - 1
        return (d - df) / math.sqrt(2 * df) > OVERDISPERSED_Z

    @staticmethod
    def _hot(h: int, n: int, base: float) -> bool:
        if h < 2:
            return False
        if base <= 0:
            return True
        return poisson_tail(h, n * base) < HOT_P

    def _episode(self, seconds, a: int, b: int, count: int, what: str) -> Episode:
        t0 = self.t0 or 0
        chances = sum(self.n.get(k, 0) for k in range(a, b + 1))
        return Episode(seconds(t0 + a * self.width), seconds(t0 + (b + 1) * self.width), count, what, chances)


def poisson_tail(k: int, mu: float) -> float:
    """P(X >= k) for a Poisson of mean mu."""
    if k <= 0:
        return 1.0
    term = math.exp(-mu)
    below = term
    for i in range(1, k):
        term *= mu / i
        below += term
    return max(0.0, 1.0 - below)
