"""Headless Chromium driven over the DevTools protocol, for the browser view (`sniffer serve`).

Debian's `chromium` runs headless with `--remote-debugging-port=0`; it writes the port it chose to
DevToolsActivePort in its profile folder, and one websocket (aiohttp, which textual-serve already
needs) to the page carries the protocol's commands: navigate, type keys, evaluate JavaScript.

The page is textual-serve's: xterm.js draws the app's screen on a canvas, so the text is read from
xterm.js's own buffer.  The page's client keeps its xterm.js Terminal in a property named
`terminal`; a script run before the page's own (Page.addScriptToEvaluateOnNewDocument) catches that
assignment and keeps the Terminal as `window.__terminal`.  `screen()` returns its rows as text.

The browser is in a process group of its own and dies with the process that started it (lifeline),
so `close()` (or a crash of the test) leaves no Chromium behind.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import shutil
import signal
import subprocess
import time

from sniffer.processes.parent_death import die_with_parent

FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--no-default-browser-check",
    # this machine's network is closed: no background connections, no updates, no crash uploads
    "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-crash-reporter",
    "--disable-breakpad", "--disable-dev-shm-usage", "--remote-debugging-port=0", "--window-size=1400,900",
]

CATCH_TERMINAL = """
Object.defineProperty(Object.prototype, "terminal", {
  configurable: true,
  set(value) {
    Object.defineProperty(this, "terminal", {value, writable: true, configurable: true, enumerable: true});
    if (value && value.buffer && value.buffer.active) window.__terminal = value;
  },
});
"""

SCREEN = """(() => {
  const t = window.__terminal;
  if (!t) return null;
  const b = t.buffer.active, rows = [];
  for (let y = 0; y < t.rows; y++) {
    const line = b.getLine(b.viewportY + y);
    rows.push(line ? line.translateToString(true) : "");
  }
  return rows.join("\\n");
})()"""

# arms window.__shown: a promise of the milliseconds from the next key the page gets (keydown) to the
# first write xterm.js parses after which the terminal's text holds `marker`
ARM_KEY_TO_TEXT = """((marker) => {
  const screen = () => %s;
  if (screen().includes(marker)) throw new Error("already on the screen: " + marker);
  let keyAt = null;
  window.addEventListener("keydown", () => { keyAt ??= performance.now(); }, {capture: true, once: true});
  window.__shown = new Promise((resolve) => {
    const sub = window.__terminal.onWriteParsed(() => {
      if (keyAt !== null && screen().includes(marker)) { sub.dispose(); resolve(performance.now() - keyAt); }
    });
  });
})""" % SCREEN

# key name -> (key, code, Windows virtual key code, text)
SPECIAL_KEYS = {
    "enter": ("Enter", "Enter", 13, "\r"), "escape": ("Escape", "Escape", 27, ""),
    "up": ("ArrowUp", "ArrowUp", 38, ""), "down": ("ArrowDown", "ArrowDown", 40, ""),
    "home": ("Home", "Home", 36, ""), "end": ("End", "End", 35, ""), "backspace": ("Backspace", "Backspace", 8, ""),
}


class BrowserError(Exception):
    """Chromium could not be started or driven; the message says why."""


def find_chromium() -> str | None:
    """The Chromium binary: $CHROMIUM, else Debian's `chromium` (or `chromium-browser`) on PATH."""
    return os.environ.get("CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")


def _key_event(ch: str) -> tuple[str, str, int, str]:
    if ch in SPECIAL_KEYS:
        return SPECIAL_KEYS[ch]
    if len(ch) != 1:
        raise ValueError(f"no key named {ch!r}")
    if ch.isalpha():
        return ch, f"Key{ch.upper()}", ord(ch.upper()), ch
    if ch.isdigit():
        return ch, f"Digit{ch}", ord(ch), ch
    return ch, "", 0, ch  # punctuation: the text is what xterm.js sends


class Chromium:
    """One headless Chromium with one page: `async with await Chromium.launch(profile) as browser:`."""

    def __init__(self, proc: subprocess.Popen, profile: str, log_path: str) -> None:
        self.proc = proc
        self.profile = profile
        self.log_path = log_path
        self._http = None
        self._ws = None
        self._ids = itertools.count(1)
        self._pending: dict[int, asyncio.Future] = {}
        self._reader: asyncio.Task | None = None
        self.on_event = None  # called with (method, params) of each event the page sends (after Log.enable ...)

    # ---------------------------------------------------------------- start and stop
    @classmethod
    async def launch(cls, profile: str, timeout: float = 60.0) -> Chromium:
        """Start Chromium with a new profile folder and open its page's DevTools websocket."""
        binary = find_chromium()
        if binary is None:
            raise BrowserError("no chromium on PATH (Debian: apt-get install chromium; scripts/install-system-deps.sh)")
        os.makedirs(profile, exist_ok=True)
        if os.path.exists(os.path.join(profile, "DevToolsActivePort")):  # an earlier browser's
            os.remove(os.path.join(profile, "DevToolsActivePort"))
        log_path = os.path.join(profile, "chromium.log")
        # its crash handler (which leaves the process group) keeps its reports under XDG_CONFIG_HOME: in the
        # profile too, so every process of this browser names the profile folder
        env = dict(os.environ, XDG_CONFIG_HOME=os.path.join(profile, "config"),
                   XDG_CACHE_HOME=os.path.join(profile, "cache"))
        with open(log_path, "w") as log:
            proc = subprocess.Popen([binary, *FLAGS, f"--user-data-dir={profile}", "about:blank"], env=env,
                                    stdin=subprocess.DEVNULL, stdout=log, stderr=log, start_new_session=True,
                                    preexec_fn=lambda: die_with_parent(signal.SIGKILL))
        browser = cls(proc, profile, log_path)
        try:
            await browser._connect(timeout)
        except BaseException:
            if browser._http is not None:
                await browser._http.close()
            browser.kill()
            raise
        return browser

    def _why(self, what: str) -> BrowserError:
        with open(self.log_path, errors="replace") as f:
            tail = f.read()[-2000:]
        return BrowserError(f"{what}; chromium said:\n{tail}")

    def _port(self) -> int | None:
        """The DevTools port, once Chromium has written DevToolsActivePort (its port, a newline, a path)."""
        try:
            with open(os.path.join(self.profile, "DevToolsActivePort")) as f:
                first, newline, _ = f.read().partition("\n")
        except OSError:
            return None
        return int(first) if newline and first.isdigit() else None

    async def _connect(self, timeout: float) -> None:
        import aiohttp

        deadline = time.monotonic() + timeout
        while (port := self._port()) is None:
            if self.proc.poll() is not None:
                raise self._why(f"chromium exited ({self.proc.returncode}) before it listened")
            if time.monotonic() > deadline:
                raise self._why(f"chromium did not listen within {timeout:.0f} s")
            await asyncio.sleep(0.05)
        self._http = aiohttp.ClientSession()
        try:
            async with self._http.get(f"http://127.0.0.1:{port}/json/list") as r:
                pages = [t for t in await r.json(content_type=None) if t.get("type") == "page"]
            if not pages:
                raise self._why("chromium has no page")
            self._ws = await self._http.ws_connect(pages[0]["webSocketDebuggerUrl"], max_msg_size=0)
        except aiohttp.ClientError as e:
            raise self._why(f"chromium's DevTools port {port}: {e}") from None
        self._reader = asyncio.create_task(self._read())
        await self.send("Page.enable")
        await self.send("Runtime.enable")
        await self.send("Page.addScriptToEvaluateOnNewDocument", source=CATCH_TERMINAL)
        await self.send("Emulation.setFocusEmulationEnabled", enabled=True)  # a headless page keeps key focus

    async def close(self) -> None:
        """Close the browser (Browser.close, then its process group), and the websocket."""
        if self._ws is not None and not self._ws.closed:
            try:
                await asyncio.wait_for(self.send("Browser.close"), 5)
            except (BrowserError, TimeoutError, ConnectionError):
                pass
        if self._reader is not None:
            self._reader.cancel()
        if self._ws is not None:
            await self._ws.close()
        if self._http is not None:
            await self._http.close()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            pass
        self.kill()

    def kill(self) -> None:
        """Kill what is left of the browser: its process group (renderers, zygote, GPU process)."""
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()

    async def __aenter__(self) -> Chromium:
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()

    # ---------------------------------------------------------------- the protocol
    async def _read(self) -> None:
        import aiohttp

        async for msg in self._ws:
            if msg.type != aiohttp.WSMsgType.TEXT:
                break
            data = json.loads(msg.data)
            if "method" in data and self.on_event is not None:
                self.on_event(data["method"], data.get("params", {}))
            fut = self._pending.pop(data.get("id"), None)
            if fut is not None and not fut.done():
                fut.set_result(data)
        for fut in self._pending.values():
            if not fut.done():
                fut.set_exception(BrowserError("chromium closed the DevTools connection"))

    async def send(self, method: str, **params) -> dict:
        """One DevTools command; its result, or BrowserError with the protocol's error."""
        n = next(self._ids)
        fut = asyncio.get_running_loop().create_future()
        self._pending[n] = fut
        await self._ws.send_str(json.dumps({"id": n, "method": method, "params": params}))
        data = await fut
        if "error" in data:
            raise BrowserError(f"{method}: {data['error'].get('message')}")
        return data.get("result", {})

    async def evaluate(self, expression: str, await_promise: bool = False):
        r = await self.send("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=await_promise)
        if "exceptionDetails" in r:
            raise BrowserError(f"page script failed: {r['exceptionDetails'].get('text')} "
                               f"{r['result'].get('description', '')}")
        return r["result"].get("value")

    # ---------------------------------------------------------------- what a person does
    async def open(self, url: str, timeout: float = 60.0) -> None:
        """Load the page, wait for its terminal and give it the keyboard (as a click into it would)."""
        r = await self.send("Page.navigate", url=url)
        if r.get("errorText"):
            raise BrowserError(f"{url}: {r['errorText']}")
        deadline = time.monotonic() + timeout
        while not await self.evaluate("!!window.__terminal"):
            if time.monotonic() > deadline:
                raise BrowserError(f"{url}: no terminal in the page within {timeout:.0f} s (did textual-serve's "
                                   f"page change? see CATCH_TERMINAL)")
            await asyncio.sleep(0.05)
        await self.evaluate("window.__terminal.focus()")

    async def press(self, *keys: str) -> None:
        """Type keys as a person would: 'q', '/', 'enter', 'escape', 'up' ... (a keyDown and a keyUp each)."""
        for name in keys:
            key, code, vk, text = _key_event(name)
            down = {"key": key, "code": code, "windowsVirtualKeyCode": vk, "nativeVirtualKeyCode": vk}
            await self.send("Input.dispatchKeyEvent", type="keyDown" if text else "rawKeyDown", text=text, **down)
            await self.send("Input.dispatchKeyEvent", type="keyUp", **down)

    async def type(self, text: str) -> None:
        await self.press(*text)

    async def screen(self) -> str | None:
        """The terminal's text, one line a row; None until the page's terminal exists."""
        return await self.evaluate(SCREEN)

    async def key_to_text(self, key: str, marker: str, timeout: float = 60.0) -> float:
        """Press `key`; the milliseconds, timed in the page, from its keydown to the first write to the
        terminal after which the screen holds `marker` (not on the screen before the key)."""
        await self.evaluate(f"{ARM_KEY_TO_TEXT}({json.dumps(marker)})")
        await self.press(key)
        return await asyncio.wait_for(self.evaluate("window.__shown", await_promise=True), timeout)

    async def wait_for(self, cond, what: str, timeout: float = 60.0) -> str:
        """Wait until cond(screen text) holds; the screen then.  Fails with the last screen seen."""
        deadline = time.monotonic() + timeout
        seen = None
        while True:
            seen = await self.screen()
            if seen is not None and cond(seen):
                return seen
            if time.monotonic() > deadline:
                raise AssertionError(f"gave up waiting for {what}; the page showed:\n{seen}")
            await asyncio.sleep(0.05)
