"""The plant page of `softplc plant run --web PORT` and `plant up` (issue 35; the view of
`plant up` comes from the daemons' monitors, softplc.commands.plantweb, with a link to
each one's own monitor): each controller's state,
scans, scan time and link health, and the Remote Link words moving, refreshed twice a
second (the view: softplc.plant.view). Read-only, on loopback only, with the monitor's
Host and Origin checks (`Guard`: no DNS rebinding). The plant loop publishes a view
(`plant_view`) between two steps; the page's thread only serves the last one, so it never
reads a plant mid-step.

    GET /            the page
    GET /api/plant   the last view, JSON
"""

from __future__ import annotations

import asyncio
import json
import threading
from typing import Any

from aiohttp import web

from softplc.web.errors import ApiError
from softplc.web.security import Guard
from softplc.web.site import http_url, serve

HOST = "127.0.0.1"
START_TIMEOUT_S = 10.0


PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>softplc plant</title>
<style>body{font-family:sans-serif;margin:1em}table{border-collapse:collapse}
td,th{border:1px solid #999;padding:2px 8px;text-align:left}.bad{color:#b00}
.ok{color:#070}</style></head><body>
<h1>plant <span id="name"></span> <small>t = <span id="time"></span> s</small></h1>
<table><thead><tr><th>controller</th><th>state</th><th>scans</th><th>scan &micro;s</th>
<th>link</th><th>%SW111</th><th>%SW112</th><th>words (station: sent / received)</th>
<th>monitor</th></tr></thead><tbody id="rows"></tbody></table>
<script>
function cell(tr, text, cls) {
  const td = document.createElement("td"); td.textContent = text;
  if (cls) td.className = cls; tr.appendChild(td);
}
async function refresh() {
  try {
    const v = await (await fetch("/api/plant")).json();
    document.getElementById("name").textContent = v.name;
    document.getElementById("time").textContent = v.time.toFixed(2);
    const rows = document.getElementById("rows"); rows.textContent = "";
    for (const c of v.controllers) {
      const tr = document.createElement("tr");
      cell(tr, c.name); cell(tr, c.state, c.state === "RUN" ? "ok" : "bad");
      cell(tr, c.scans); cell(tr, c.scan_us);
      cell(tr, c.address === null ? "-" : "address " + c.address);
      cell(tr, c.link ? c.link.status.toString(2).padStart(8, "0") : "-");
      cell(tr, c.link ? c.link.error : "-", c.link && c.link.error ? "bad" : "ok");
      cell(tr, Object.entries(c.words).map(([s, w]) => s + ": " + w.sent.join(",")
        + " / " + w.received.join(",") + (w.present === false ? " (absent)" : "")).join("; "));
      const td = document.createElement("td");  // `plant up`: the controller's own monitor
      if (c.monitor) {
        const a = document.createElement("a"); a.href = c.monitor; a.target = "_blank";
        a.className = "monitor"; a.textContent = "open"; td.appendChild(a);
      } else td.textContent = "-";
      tr.appendChild(td);
      rows.appendChild(tr);
    }
  } catch (e) { document.getElementById("time").textContent = "(plant stopped)"; }
}
refresh(); setInterval(refresh, 500);
</script></body></html>
"""


class PlantPage:
    """The page's server, in a thread of its own; `publish(view)` from the plant loop."""

    def __init__(self, port: int):
        self.port = port
        self.guard = Guard(HOST)
        self.view: dict[str, Any] = {}
        self.loop = asyncio.new_event_loop()
        self._runner: web.AppRunner | None = None
        self._thread = threading.Thread(target=self.loop.run_forever, name="plant-page",
                                        daemon=True)

    def publish(self, view: dict[str, Any]) -> None:
        self.view = view  # one reference swapped: the server reads a whole view

    @web.middleware
    async def _guard(self, request: web.Request, handler: Any) -> web.StreamResponse:
        try:
            self.guard.check(request, change=False)
        except ApiError as e:
            return web.json_response({"error": str(e)}, status=e.status)
        return await handler(request)

    async def _start(self) -> None:
        app = web.Application(middlewares=[self._guard])
        app.router.add_get("/", lambda _: web.Response(text=PAGE, content_type="text/html"))
        app.router.add_get("/api/plant", lambda _: web.Response(
            text=json.dumps(self.view), content_type="application/json"))
        self._runner, self.port = await serve(app, HOST, self.port)

    def start(self) -> str:
        """Serve; the page's URL."""
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self._start(), self.loop).result(START_TIMEOUT_S)
        return http_url(HOST, self.port)

    def stop(self) -> None:
        if self._runner is not None:
            asyncio.run_coroutine_threadsafe(self._runner.cleanup(), self.loop).result(
                START_TIMEOUT_S)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(START_TIMEOUT_S)
