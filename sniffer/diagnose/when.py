"""Episodes for the findings whose own group judges them over the whole capture: retry_storm, latency_drift,
answers_broadcast, wrong_line_settings, poll_cycle, params_changed.

The engine hands this group every request (`WhenGroup.request`) and, once the groups have made their
findings, the findings (`WhenGroup.fill`): a finding of these kinds with no episodes of its own gets them here.

* retry_storm: the master's requests per window of time, the retries among them hit (episodes.Windows):
  retries all along are one episode, retries that come in bursts (a unit out for a while, noise during a
  ramp) an episode each;
* latency_drift: the unit's answer time per stretch (Unit.lat_bins); the stretches whose median has left
  the first third's by a quarter of the drift or more, in the drift's direction, one apart joined, are its
  episodes (a drift that grows all along: one episode from where it left to the end);
* answers_broadcast: the link's broadcasts per window, those the unit answered hit;
* wrong_line_settings: the link's frames per window, the damaged ones hit (what was read at the wrong settings);
* poll_cycle: a full line whose cycle stretches, where the retries and unanswered requests came; any other one
  episode over the span, counting the cycles;
* params_changed: one episode over the span, counting the parameters that differ (the values read are the
  state at the end, not events).
(eeprom_wear, params_not_saved and poll_redundant carry their own: params.py, polls.py.)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.diagnose.codesets import RETRY, UNANSWERED
from sniffer.diagnose.episodes import Episode, Windows, keep
from sniffer.diagnose.finding import Finding
from sniffer.diagnose.state import Group, Link, Unit

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

DEPARTED = 0.25  # of the drift (last third's median - first third's): a stretch this far along has left
JOIN = 4  # windows: retries come with what misses answers, quiet seconds between its bursts (episodes.Windows)


class WhenGroup(Group):
    def __init__(self) -> None:
        self.retries: dict[str, Windows] = {}  # link -> its requests in time, the retries hit
        self.stretched: dict[str, Windows] = {}  # link -> its requests in time, retries and unanswered ones hit
        self.broadcasts: dict[str, dict[int, Windows]] = {}  # link -> unit -> broadcasts in time, its answers hit

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if not f.unit:
            for w in self.broadcasts.get(link.name, {}).values():
                w.add(f.t_ns)
            return
        w = self.retries.get(link.name)
        if w is None:
            w = self.retries[link.name] = Windows()
            self.stretched[link.name] = Windows()
        retry = bool(codes) and not RETRY.isdisjoint(codes)
        w.add(f.t_ns, retry)
        self.stretched[link.name].add(f.t_ns, retry or bool(codes) and not UNANSWERED.isdisjoint(codes))

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if codes and "pair.broadcast_response" in codes and f.unit is not None:
            units = self.broadcasts.setdefault(link.name, {})
            w = units.get(f.unit)
            if w is None:
                units[f.unit] = w = Windows()
                w.add(f.t_ns, True)  # (its chances from its first answer on: the broadcasts before were not kept)
            else:
                w.mark(f.t_ns)

    def fill(self, d: Diagnosis, findings: list[Finding]) -> None:
        for f in findings:
            if f.episodes:
                continue
            if f.kind == "retry_storm" and f.link in self.retries:
                f.episodes = self.retries[f.link].episodes(d.seconds, "retries", join=JOIN)
            elif f.kind == "latency_drift" and f.link in d.links and f.unit in d.links[f.link].units:
                f.episodes = drift_episodes(d, d.links[f.link].units[f.unit])
            elif f.kind == "answers_broadcast" and f.unit in self.broadcasts.get(f.link, {}):
                f.episodes = self.broadcasts[f.link][f.unit].episodes(d.seconds, "answers to broadcasts")
            elif f.kind == "wrong_line_settings" and f.link in d.links:
                f.episodes = d.links[f.link].damage.episodes(d.seconds, "frames damaged as read")
            elif f.kind == "poll_cycle" and f.severity != "info" and f.link in self.stretched:
                f.episodes = self.stretched[f.link].episodes(d.seconds, "retries or unanswered requests", join=JOIN)
            elif f.kind in ("poll_cycle", "params_changed") and f.t_start is not None and f.t_end is not None:
                f.episodes = [_span(f)]
            else:
                continue
            f.episode_count = len(f.episodes)
            f.episodes = keep(f.episodes)  # (the first and last few, as a finding made with them keeps)


def _span(f: Finding) -> Episode:
    """One episode over the finding's span: a state rather than events (the cycle all along, values at the end)."""
    if f.kind == "poll_cycle":
        cycle = f.evidence.get("cycle_ms") or 0
        n = int((f.t_end - f.t_start) * 1e3 / cycle) if cycle > 0 else 0
        return Episode(f.t_start, f.t_end, n, "poll cycles")
    return Episode(f.t_start, f.t_end, int(f.evidence.get("changed", 0)), "parameters that differ from the reference")


def drift_episodes(d: Diagnosis, u: Unit) -> list[Episode]:
    """The stretches of a unit's answer time that left where it was in the first third (see the module doc)."""
    bins = u.lat_bins
    meds = bins.medians()
    if len(meds) < 3 or bins.t0 is None:
        return []
    third = max(len(meds) // 3, 1)
    a = sorted(m[1] for m in meds[:third])[third // 2]
    b = sorted(m[1] for m in meds[-third:])[third // 2]
    step = DEPARTED * (b - a)
    if step == 0:
        return []
    half = bins.width / 2e9
    runs: list[list] = []  # [from_s, to_s, answers] of stretches one apart or less
    for mid, med, n in meds:
        if (med - a) / step < 1.0:  # (step carries the drift's sign)
            continue
        t0, t1 = mid - half, mid + half
        if runs and t0 - runs[-1][1] <= 2 * half + 1e-9:
            runs[-1][1], runs[-1][2] = t1, runs[-1][2] + n
        else:
            runs.append([t0, t1, n])
    base = d.seconds(bins.t0) or 0.0
    way = "slower" if step > 0 else "quicker"
    what = f"answers {abs(step):.1f} ms or more {way} than at the start"
    return [Episode(base + x0, base + x1, n, what) for x0, x1, n in runs]
