"""The report as a person sees it: `sniffer report` writes the page, headless Chromium opens it from a file://
URL with the network switched off, and every plot must have drawn its data, with no error in the console.

Real parts: the CLI writes the report from simulated captures (captures/sim), Debian's `chromium` loads it
(tests/headless_chromium.py); the page's own record of its plots (`window.__report.plots`) is checked
against the canvases: each exists with a non-zero size and holds pixels of its series' colours.  A drag
across a time plot zooms it (the x range shrinks), Shift+drag pans it (the range moves, its width kept),
and a double-click shows everything again.  The screenshot goes to docs/report.png with
SNIFFER_REPORT_DOCS=1 (docs/report.md shows it).
"""

from __future__ import annotations

import asyncio
import base64
import os
from pathlib import Path

import pytest
from headless_chromium import BrowserError, Chromium

from sniffer.cli import main

SIM = Path(__file__).resolve().parent.parent / "captures" / "sim"
DOCS = Path(__file__).resolve().parent.parent / "docs"

# per plot: canvas size, the series' drawn count and whether pixels of a series colour are on the canvas
PLOT_CHECK = """(() => {
  const hex = (c) => [1, 3, 5].map((i) => parseInt(c.slice(i, i + 2), 16));
  return window.__report.plots.map((p) => {
    const cv = p.u.ctx.canvas, ctx = p.u.ctx;
    const img = ctx.getImageData(0, 0, cv.width, cv.height).data;
    const want = p.colors.filter((c) => /^#[0-9a-f]{6}/i.test(c)).map(hex);
    let coloured = 0;
    for (let i = 0; i < img.length; i += 4) {
      if (img[i + 3] < 200) continue;
      for (const [r, g, b] of want) {
        if (Math.abs(img[i] - r) + Math.abs(img[i + 1] - g) + Math.abs(img[i + 2] - b) < 40) { coloured++; break; }
      }
    }
    const box = cv.getBoundingClientRect();
    return {id: p.id, kind: p.kind, points: p.points, drawn: p.drawn, width: box.width, height: box.height,
            coloured: coloured, custom: p.colors.length === 0};
  });
})()"""

X_RANGE = "(() => { const p = window.__report.plots.find((p) => p.id === %r); " \
          "return [p.u.scales.x.min, p.u.scales.x.max]; })()"
OVER_BOX = "(() => { const p = window.__report.plots.find((p) => p.id === %r); " \
           "p.u.over.scrollIntoView({block: 'center'}); const r = p.u.over.getBoundingClientRect(); " \
           "return [r.left, r.top, r.width, r.height]; })()"


def write_report(tmp_path, *extra) -> Path:
    out = tmp_path / "report.html"
    here = os.getcwd()
    os.chdir(SIM)  # the captures named as a user in that folder names them (the page shows what was typed)
    try:
        rc = main(["report", "errors.mcap", "tds-v8.mcap", "--out", str(out), *extra])
    finally:
        os.chdir(here)
    assert rc == 0 and out.is_file()
    return out


async def launch(profile: str) -> Chromium:
    try:
        return await Chromium.launch(profile, timeout=120)
    except BrowserError as e:
        if os.environ.get("CI"):
            pytest.fail(f"headless chromium could not be started: {e}")
        pytest.skip(f"headless chromium could not be started: {e}")


async def load_offline(browser: Chromium, url: str) -> tuple[list[str], list[str]]:
    """Open `url` with the network emulated offline; (console errors and exceptions, URLs the page asked for)."""
    errors: list[str] = []
    requests: list[str] = []

    def on_event(method: str, params: dict) -> None:
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", [])))
        elif method == "Runtime.exceptionThrown":
            d = params.get("exceptionDetails", {})
            errors.append(f"{d.get('text')} {d.get('exception', {}).get('description', '')}")
        elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
            errors.append(f"{params['entry'].get('source')}: {params['entry'].get('text')}")
        elif method == "Network.requestWillBeSent":
            requests.append(params["request"]["url"])

    browser.on_event = on_event
    await browser.send("Log.enable")
    await browser.send("Network.enable")
    await browser.send("Network.emulateNetworkConditions", offline=True, latency=0, downloadThroughput=-1,
                       uploadThroughput=-1)
    await browser.send("Emulation.setDeviceMetricsOverride", width=1400, height=900, deviceScaleFactor=1, mobile=False)
    r = await browser.send("Page.navigate", url=url)
    assert not r.get("errorText"), r
    for _ in range(600):
        if await browser.evaluate("document.readyState === 'complete' && !!(window.__report && window.__report.ready)"):
            break
        await asyncio.sleep(0.05)
    await asyncio.sleep(0.3)  # console messages of the last script reach us
    return errors, requests


async def drag(browser: Chromium, x0: float, y: float, x1: float, modifiers: int = 0) -> None:
    await browser.send("Input.dispatchMouseEvent", type="mouseMoved", x=x0, y=y, modifiers=modifiers)
    await browser.send("Input.dispatchMouseEvent", type="mousePressed", x=x0, y=y, button="left", clickCount=1,
                       modifiers=modifiers)
    for k in range(1, 11):
        await browser.send("Input.dispatchMouseEvent", type="mouseMoved", x=x0 + (x1 - x0) * k / 10, y=y,
                           button="left", modifiers=modifiers)
    await browser.send("Input.dispatchMouseEvent", type="mouseReleased", x=x1, y=y, button="left", clickCount=1,
                       modifiers=modifiers)


def test_a_report_without_frames_opens_without_errors(tmp_path):
    empty = tmp_path / "empty.mcap"
    assert main(["simulate", "--duration", "0.001", "--out", str(empty)]) == 0
    out = tmp_path / "empty.html"
    assert main(["report", str(empty), "--out", str(out)]) == 0

    async def go():
        browser = await launch(str(tmp_path / "profile"))
        async with browser:
            errors, _ = await load_offline(browser, out.as_uri())
            assert errors == [] and await browser.evaluate("window.__report.errors") == []
            assert await browser.evaluate("document.querySelectorAll('figure.plot').length") == 0
            assert "No frames." in await browser.evaluate("document.body.innerText")

    asyncio.run(go())


def test_report_in_chromium(tmp_path):
    out = write_report(tmp_path)

    async def go():
        browser = await launch(str(tmp_path / "profile"))
        async with browser:
            errors, requests = await load_offline(browser, out.as_uri())
            assert errors == [], errors
            assert await browser.evaluate("window.__report.errors") == []
            assert [u for u in requests if not u.startswith(("file:", "data:"))] == []  # nothing from the network
            plots = await browser.evaluate(PLOT_CHECK)
            ids = {p["id"] for p in plots}
            figures = await browser.evaluate("Array.from(document.querySelectorAll('figure.plot')).map(f => f.id)")
            assert set(figures) == ids  # every figure the page announces became a plot
            assert {"plot-lat-hist", "plot-lat-time", "plot-polls", "plot-util", "plot-errors", "plot-turn",
                    "plot-violations", "plot-timeline", "plot-reg-0"} <= ids
            for p in plots:
                assert p["width"] > 300 and p["height"] > 100, p
                assert p["points"] > 0 and p["drawn"] > 0, p
                assert p["custom"] or p["coloured"] > 20, p  # the series' colours are on the canvas

            # zoom: drag across the middle of the utilisation plot
            full = await browser.evaluate(X_RANGE % "plot-util")
            left, top, width, height = await browser.evaluate(OVER_BOX % "plot-util")
            y = top + height / 2
            await drag(browser, left + width * 0.3, y, left + width * 0.6)
            zoomed = await browser.evaluate(X_RANGE % "plot-util")
            assert zoomed[1] - zoomed[0] < 0.5 * (full[1] - full[0]), (full, zoomed)
            # the other time plots followed (zoom all together is on)
            other = await browser.evaluate(X_RANGE % "plot-errors")
            assert other == pytest.approx(zoomed)
            # pan: Shift+drag to the left moves the range right, keeping its width
            await drag(browser, left + width * 0.6, y, left + width * 0.4, modifiers=8)
            panned = await browser.evaluate(X_RANGE % "plot-util")
            assert panned[1] - panned[0] == pytest.approx(zoomed[1] - zoomed[0], rel=1e-6)
            assert panned[0] > zoomed[0]
            # double-click: everything again
            for kind in ("mousePressed", "mouseReleased"):
                await browser.send("Input.dispatchMouseEvent", type=kind, x=left + width / 2, y=y, button="left",
                                   clickCount=2)
            assert await browser.evaluate(X_RANGE % "plot-util") == pytest.approx(full)

            await browser.evaluate("window.scrollTo(0, 0)")
            shot = await browser.send("Page.captureScreenshot", format="png", captureBeyondViewport=True,
                                      clip={"x": 0, "y": 0, "width": 1400, "height": 2400, "scale": 1})
            png = base64.b64decode(shot["data"])
            assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 50_000
            if os.environ.get("SNIFFER_REPORT_DOCS"):
                (DOCS / "report.png").write_bytes(png)

    asyncio.run(go())
