"""The replay page's server (aiohttp): a counterexample played on the ladder, read-only.

    GET /                      the replay page (static/replay.html, replay.js)
    GET /api/replay            the requirement, the scans, the violating scan, the rungs
    GET /api/replay/scan/N     go to position N (0 = cold start): its inputs, values,
                               status and every rung as SVG, the requirement's labels
                               highlighted

There is no POST route: nothing of a host or a plant reaches the controller, which only
ever runs the trace's inputs (`verify.player`). It listens on loopback only, and every
request goes through the web monitor's Host/Origin checks (`security.Guard`: DNS rebinding).
"""

from __future__ import annotations

from typing import Any

from aiohttp import web

from softplc.errors import SoftPLCError
from softplc.verify.player import TracePlayer
from softplc.web.control import ApiError
from softplc.web.live import dumps
from softplc.web.security import Guard, is_loopback
from softplc.web.server import static_dir
from softplc.web.site import Site


def _json(data: Any, status: int = 200) -> web.Response:
    return web.Response(text=dumps(data), status=status, content_type="application/json")


class ReplayServer(Site):
    def __init__(self, player: TracePlayer, program: str, host: str = "127.0.0.1",
                 port: int = 0):
        if not is_loopback(host):
            raise SoftPLCError(f"softplc replay: the page listens on loopback only, not "
                               f"{host}")
        self.player = player
        self.program = program
        self.host, self.port = host, port
        self.guard = Guard(host)
        self.app = web.Application(middlewares=[self._errors])
        r = self.app.router
        r.add_get("/", self._index)
        r.add_get("/api/replay", self._info)
        r.add_get("/api/replay/scan/{n}", self._scan)
        r.add_static("/static/", static_dir())

    @web.middleware
    async def _errors(self, request: web.Request, handler: Any) -> web.StreamResponse:
        try:
            self.guard.check(request, change=request.method != "GET")
            return await handler(request)
        except ApiError as e:
            return _json({"error": str(e)}, e.status)
        except SoftPLCError as e:
            return _json({"error": str(e)}, 400)

    async def _index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(static_dir() / "replay.html")

    async def _info(self, request: web.Request) -> web.Response:
        return _json(self.player.info() | {"program": self.program})

    async def _scan(self, request: web.Request) -> web.Response:
        text = request.match_info["n"]
        if not text.isdigit() or len(text) > len(str(self.player.total)):
            raise ApiError(f"scan {text[:20]!r}: a number from 0 to {self.player.total}")
        n = self.player.goto(int(text))
        return _json(self.player.frame() | {"scan": n, "rungs": self.player.rung_svgs()})


__all__ = ["ReplayServer"]
