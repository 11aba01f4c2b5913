"""Screenshots of the built site in headless Chromium, each page scrolled to an element.

    mkdocs build -d /tmp/site && python docs/_tools/screenshots.py /tmp/site /tmp/shots

Serves SITE on a local port, drives ``chromium --headless`` through the DevTools protocol
(tornado's websocket client, installed with Jupyter) and writes one PNG per page in OUT: the
home page, the paper notebook's figures, the ``through_focus`` and ``Panel`` API entries and
the VSOTF's equation. Not part of the tests (it needs a Chromium binary, e.g. the Debian
package ``chromium``); a way to look at the pages as a reader does.
"""

from __future__ import annotations

import asyncio
import base64
import functools
import http.server
import json
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

PAGES = {
    "home": "",
    "paper_notebook": "notebooks/reproduce_paper/#figures-311",
    "through_focus": "api/vision/#lfjax.vision.focus.through_focus",
    "panel": "api/display/#lfjax.display.panel.Panel",
    "vsotf_equation": "api/kernel/#lfjax.kernel.metrics.vsotf",
    "cli": "cli/",
}
DEBUG_PORT = 9333


async def _shoot(base_url: str, out: Path) -> None:
    from tornado.websocket import websocket_connect

    browser = subprocess.Popen(
        ["chromium", "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         f"--remote-debugging-port={DEBUG_PORT}", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(100):  # the browser takes a moment to open its port
            try:
                tabs = json.load(urllib.request.urlopen(f"http://127.0.0.1:{DEBUG_PORT}/json"))
                break
            except OSError:
                time.sleep(0.2)
        page = next(t for t in tabs if t["type"] == "page")
        ws = await websocket_connect(page["webSocketDebuggerUrl"], max_message_size=2**28)
        counter = 0

        async def call(method: str, **params):
            nonlocal counter
            counter += 1
            await ws.write_message(json.dumps({"id": counter, "method": method, "params": params}))
            while True:
                message = json.loads(await ws.read_message())
                if message.get("id") == counter:
                    return message.get("result", message)

        await call("Emulation.setDeviceMetricsOverride", width=1280, height=1600,
                   deviceScaleFactor=1, mobile=False)
        for name, path in PAGES.items():
            address, _, anchor = path.partition("#")
            await call("Page.navigate", url=base_url + address)
            await asyncio.sleep(4)  # load and lay out (the API pages are large)
            if anchor:  # headless screenshots ignore the URL's fragment: scroll by script
                await call("Runtime.evaluate", expression=(
                    f"document.getElementById({anchor!r}).scrollIntoView(); scrollBy(0, -70)"))
                await asyncio.sleep(1)
            shot = await call("Page.captureScreenshot", format="png")
            (out / f"{name}.png").write_bytes(base64.b64decode(shot["data"]))
            print("wrote", out / f"{name}.png")
    finally:
        browser.terminate()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # one line per file would bury the result
        pass


def main(site: str, out: str) -> None:
    Path(out).mkdir(parents=True, exist_ok=True)
    handler = functools.partial(_QuietHandler, directory=site)
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        asyncio.run(_shoot(f"http://127.0.0.1:{server.server_port}/", Path(out)))
    finally:
        server.shutdown()


if __name__ == "__main__":
    main(*sys.argv[1:3])
