"""The latency histogram of the Transactions tab: a unit's (or every unit's) figures and latencies in bins.

Textual-free (rich only, for the drawing).  The figures are the unit's `sniffer.analysis.unitfigures.UnitFigures`
(the same numbers the Units tab, the report, `status`, `diff` and MQTT show: quantiles by the nearest
rank, timeouts once a request); the bins are counted from its `Latencies` when drawn.
"""

from __future__ import annotations

from rich.text import Text

# bin upper edges in ms, 1-2-5 steps over 0.5..1000 ms; a bin holds (previous edge, edge]; one more past 1000
EDGES_MS = (0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000)
BIN_LABELS = tuple(f"≤{e:g}" for e in EDGES_MS) + (f">{EDGES_MS[-1]:g}",)
_BLOCKS = " ▁▂▃▄▅▆▇█"  # eighths of a character cell
BAR_ROWS = 5
COL = 6  # characters per bin column (12 bins and the labels fit 80 columns)
_LEFT = 3  # the label column


def _ms(v: float) -> str:
    return f"{v:.3f}"  # to the microsecond, as the frames and every other view have it


def _count(n: int) -> str:
    return str(n) if n < 100_000 else f"{n // 1000}k"


def figures_line(fig) -> str:
    lat = fig.latency
    if not lat.n:
        return "no latency measured"
    approx = "" if lat.exact else " (quantiles within 0.1 %)"
    return (f"n {lat.n}  median {_ms(lat.median)}  p95 {_ms(lat.quantile(0.95))}  p99 {_ms(lat.quantile(0.99))}  "
            f"max {_ms(lat.max)} ms{approx}")


def unanswered_line(fig) -> str:
    parts = [f"timeouts {fig.timeouts}"]
    if fig.late:
        parts.append(f"late {fig.late}")
    if fig.unanswered_at_end:
        parts.append(f"unanswered at the end {fig.unanswered_at_end}")
    if fig.unmeasured:
        parts.append(f"no latency {fig.unmeasured} (read with their request)")
    return "  ".join(parts)


def histogram_text(fig, title: str, bar_rows: int = BAR_ROWS) -> Text:
    """Title and figures of a UnitFigures, the unanswered counts, then a column of block characters per bin,
    its label, its count."""
    text = Text(no_wrap=True, overflow="ellipsis")
    text.append(f"{title}: ", "bold")
    text.append(figures_line(fig) + "\n")
    text.append(unanswered_line(fig) + "\n", "yellow" if fig.timeouts else "dim")
    bins = fig.latency.bins(EDGES_MS)
    top = max(bins) or 1
    levels = [0 if c == 0 else max(1, round(c * bar_rows * 8 / top)) for c in bins]
    pad = " " * _LEFT
    for r in range(bar_rows, 0, -1):  # the top row first
        line = "".join(_BLOCKS[min(max(lv - (r - 1) * 8, 0), 8)] * (COL - 1) + " " for lv in levels)
        text.append(f"{pad}{line}\n", "cyan")
    text.append(f"{'ms':>{_LEFT - 1}} " + "".join(f"{lab:<{COL}}" for lab in BIN_LABELS) + "\n", "dim")
    text.append(f"{'n':>{_LEFT - 1}} " + "".join(f"{_count(c):<{COL}}" for c in bins))
    return text
