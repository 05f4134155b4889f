"""The browser view as a person uses it: `sniffer serve` in headless Chromium, driven by keys.

Real parts: `sniffer serve --demo` as a process on a free port of 127.0.0.1, Debian's `chromium`
headless on its page (tests/headless_chromium.py), keys typed into the page and the screen read
back from the page's terminal (xterm.js).  Every wait is on a condition, with a generous bound;
nothing is timed.  Without Chromium the test skips with the reason, except on CI (CI set), where
that is a failure: scripts/install-system-deps.sh installs it there.
"""

from __future__ import annotations

import asyncio
import os
import re
import signal
import time

import pytest
from headless_chromium import BrowserError, Chromium
from serve_helpers import HANG_S, captures_of, processes_in_session, processes_with, start_serve, wait

FRAME_ROW = re.compile(r"(->REQ|<-RSP|NOISE) u +(\d+|-)")


def frame_rows(screen: str) -> list[tuple[str, str]]:
    """(direction, unit) of each frame row on the screen."""
    return [m.groups() for m in map(FRAME_ROW.search, screen.splitlines()) if m]


def status_bar(screen: str) -> str:
    rows = [r for r in screen.splitlines() if " fr/s " in r]
    assert len(rows) == 1, screen
    return rows[0]


def left_behind(finders: dict) -> dict[str, list[int]]:
    """What each finder still finds once they all find nothing, or after HANG_S; those are then killed."""
    deadline = time.monotonic() + HANG_S
    while True:
        left = {what: find() for what, find in finders.items()}
        if not any(left.values()) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    for pid in sum(left.values(), []):
        os.kill(pid, signal.SIGKILL)
    return left


async def launch(profile: str) -> Chromium:
    """Headless Chromium, or the test fails (on CI) or skips (elsewhere) saying why it cannot start."""
    try:
        return await Chromium.launch(profile, timeout=HANG_S)
    except BrowserError as e:
        if os.environ.get("CI"):
            pytest.fail(f"headless chromium could not be started: {e}")
        pytest.skip(f"headless chromium could not be started: {e}")


async def drive(browser: Chromium, url: str, sock: str, server: int) -> None:
    await browser.open(url)
    screen = await browser.wait_for(lambda s: len(frame_rows(s)) > 5, "frames in the frame list")
    assert "demo errors" in status_bar(screen)

    await browser.press("2")
    await browser.wait_for(lambda s: "lat med" in s and re.search(r"^ 1 +generic +\d+", s, re.M), "the Units tab")
    await browser.press("1")
    await browser.wait_for(lambda s: "frame→pair" in s and frame_rows(s), "the Frames tab again")

    # every key after '/' is filter text ('u', 'e', 'q' are commands otherwise), until Enter
    await browser.press("/")
    await browser.type("u:1 role:req")
    await browser.press("enter")
    screen = await browser.wait_for(lambda s: "filter:" in status_bar(s), "the filter in the status bar")
    await browser.wait_for(lambda s: frame_rows(s) and set(frame_rows(s)) == {("->REQ", "1")},
                           "only unit 1's requests listed")
    assert "demo errors" in status_bar(screen)  # nothing quit, the view goes on

    await browser.press("?")
    await browser.wait_for(lambda s: "rs485-sniffer TUI" in s and "frames / units / registers" in s, "the help")
    await browser.press("escape")
    await browser.wait_for(lambda s: "rs485-sniffer TUI" not in s and "filter:" in status_bar(s), "the help closed")

    # q in a browser view (a viewer of the capture) closes that view; the capture goes on
    assert len(processes_with(f"attach {sock} --tui")) == 1
    await browser.press("q")
    deadline = asyncio.get_running_loop().time() + HANG_S
    while not await browser.evaluate("document.body.classList.contains('-closed')"):  # 'Session ended.'
        assert asyncio.get_running_loop().time() < deadline, "the page never said the session ended"
        await asyncio.sleep(0.05)
    wait(lambda: not processes_with(f"attach {sock} --tui"), "the closed view's viewer to exit")
    assert len(captures_of(server)) == 1

    # a new visit gets a new viewer of the same capture, with no filter
    await browser.open(url)
    screen = await browser.wait_for(lambda s: len(frame_rows(s)) > 5, "frames in a new visit")
    assert "filter:" not in status_bar(screen)


def test_serve_driven_by_keys_in_headless_chromium(tmp_path):
    pytest.importorskip("textual_serve")
    pytest.importorskip("aiohttp")
    sock, profile = tmp_path / "browser.sock", tmp_path / "chromium-profile"
    browser_session = None
    captures: list[int] = []

    async def go():
        nonlocal browser_session
        browser = await launch(str(profile))
        browser_session = browser.proc.pid  # started with a session of its own
        try:
            proc, port = start_serve(tmp_path, "--demo", "--scenario", "errors", "--no-out", "--socket", str(sock),
                                     log=tmp_path / "serve.log")
            try:
                captures.extend(captures_of(proc.pid))
                await drive(browser, f"http://127.0.0.1:{port}/", str(sock), proc.pid)
            finally:
                await browser.close()
                proc.send_signal(signal.SIGINT)
                rc = proc.wait(HANG_S)
        finally:
            browser.kill()
        log = (tmp_path / "serve.log").read_text()
        assert rc == 0, log
        assert "Traceback" not in log and "sniffer: error" not in log

    try:
        asyncio.run(go())
    finally:
        left = left_behind({"chromium": lambda: processes_in_session(browser_session) if browser_session else [],
                            "chromium (its profile)": lambda: processes_with(str(profile)),
                            "viewer or capture": lambda: processes_with(str(sock)) + [
                                p for p in captures if os.path.exists(f"/proc/{p}")]})
    assert not any(left.values()), f"processes left behind: {left}"
    assert not sock.exists()
