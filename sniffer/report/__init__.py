"""`sniffer report CAPTURE... --out report.html`: a bus-health report in one self-contained HTML file.

    collect.py    the figures, gathered as the frames pass through the capture session (flat memory)
    buckets.py    counts over time in at most 1,024 buckets;  units.py  per unit: latency, turnaround
    polls.py      poll period and jitter per request type;     timeline.py  writes and fault episodes
    page.py       the HTML: tables, the data as JSON, and report.js / report.css / uPlot inline

The plotting library is uPlot (vendor/uPlot.iife.min.js, 1.6.32 from the npm registry, MIT,
vendor/LICENSE.uPlot).  Picked on merit and size: 51 kB minified with no dependency, so the
report stays a small file that opens offline (Plotly's bundle is 3.5 MB, Bokeh's 0.8 MB plus a
Python package, ECharts' 1 MB; Chart.js needs a second plugin to zoom and pan, Flot needs
jQuery), it draws on a canvas and stays fast with tens of thousands of points, has time axes,
log scales, stepped lines, synced cursors and drag-to-zoom built in; wheel zoom and Shift+drag
pan are a few lines in report.js.  It ships with the package (no system package, no network):
a fresh clone that ran the project's own install writes reports.
"""

from __future__ import annotations

from sniffer.report.collect import Collector
from sniffer.report.page import render

__all__ = ["Collector", "render"]
