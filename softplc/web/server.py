"""The web monitor's HTTP/websocket server (aiohttp), on the daemon's asyncio loop.

    GET  /                    the monitor page (static files shipped in softplc/web/static)
    GET  /api/info            program, controller, modules, devices, rungs (and the objects
                              each uses), read-only flag, symbols
    GET  /api/status          state, scan times, overruns, Modbus clients, forced objects
    GET  /api/read?obj=%MW0:4&obj=%TM0      values of one scan
    GET  /api/resolve?obj=STARTS:2          the address a symbol names ({"address": "%MW10:2"})
    GET  /api/io              every I/O channel: value, forced, driving device
    GET  /api/ladder/N        rung N as live SVG
    GET  /api/machine?since=K simulated devices and the trace recorder's samples from K
    POST /api/write   {"object": "%MW3", "value": 5} or {"writes": [{...}, ...]}
    POST /api/force   {"object": "%I0.1", "value": 1}
    POST /api/unforce {"object": "%I0.1"} (no object: all)
    POST /api/control {"action": "run" | "stop" | "cold" | "warm"}
    GET  /api/ws              websocket: send {"subscribe": {...}}, receive updates
    GET  /api/program         the running program: IL listing, hash, time loaded, version
    POST /api/program {"program": IL, "config": TOML or null, "confirm": false,
                       "cold": false}   online change (program.py)
    GET  /api/map[?format=csv]         the Modbus map of the running program

Errors are JSON `{"error": "..."}` with status 400 (bad request), 401 (token missing or
wrong), 403 (not writable, read-only monitor, another site's page, a Host name not
allowed), 404, 409 (another program change under way), 413 (a body over 64 KiB; 4 MiB
for /api/program), 415 (a POST body that is not JSON) or 503 (the
change queue is full). Who may ask what (Host allow-list, Origin, tokens): `security.py`;
the websocket pages and their limits: `pages.py`.
"""

from __future__ import annotations

import json
import logging
from functools import partial
from importlib import resources
from pathlib import Path
from typing import Any

from aiohttp import web

from softplc.limits import BoundsError, check_digits
from softplc.modbus.server import RateLimitedLog
from softplc.web.control import ApiError, Controller
from softplc.web.live import LiveViews, dumps
from softplc.web.pages import MAX_PAGES, UPDATE_HZ, Pages
from softplc.web.program import MAX_PROGRAM_BODY, ProgramChanges
from softplc.web.security import COOKIE, Guard
from softplc.web.site import Site

log = logging.getLogger("softplc.web")

MAX_BODY = 64 * 1024


def static_dir() -> Path:
    return Path(str(resources.files("softplc.web") / "static"))


def _json_int(text: str) -> int:
    check_digits(text)  # before int(): Python's own limit is a ValueError at 4,300 digits
    return int(text)


def _json_constant(text: str) -> float:
    raise BoundsError(f"{text} is no JSON number (a finite number is expected)")


def _json(data: Any, status: int = 200) -> web.Response:
    return web.Response(text=dumps(data), status=status, content_type="application/json")


async def _resolve(ctl: Controller, request: web.Request) -> web.Response:
    """GET /api/resolve?obj=TEXT: the address a symbol, range or address names (what the
    page keeps in a table), by the daemon's resolver (softplc.twido.symbols)."""
    return _json({"address": ctl.objects.address_of(request.query.get("obj"))})


class WebServer(Site):
    def __init__(self, controller: Controller, host: str = "127.0.0.1", port: int = 8020, *,
                 token: str | None = None, read_token: str | None = None,
                 allowed_hosts: tuple[str, ...] = (), max_pages: int = MAX_PAGES,
                 update_hz: float = UPDATE_HZ):
        self.ctl = controller
        self.host = host
        self.port = port
        self.token = token
        self.guard = Guard(host, token, read_token, allowed_hosts)
        self.views = LiveViews(controller)
        self.program = ProgramChanges(controller)
        self.pages = Pages(controller, self.views, max_pages=max_pages, update_hz=update_hz)
        self.warn = RateLimitedLog(log)
        self.app = self._make_app()

    @property
    def clients(self) -> set[Any]:
        return self.pages.clients

    # -- set-up ------------------------------------------------------------------------------
    def _make_app(self) -> web.Application:
        # bodies are read by `_body`, which bounds each route (MAX_BODY, a program's more)
        app = web.Application(middlewares=[self._errors], client_max_size=MAX_PROGRAM_BODY)
        r = app.router
        r.add_get("/", self._index)
        r.add_get("/api/info", self._info)
        r.add_get("/api/status", self._status)
        r.add_get("/api/read", self._read)
        r.add_post("/api/read", self._read)
        r.add_get("/api/resolve", partial(_resolve, self.ctl))
        r.add_get("/api/io", self._io)
        r.add_get("/api/ladder/{rung}", self._ladder)
        r.add_get("/api/machine", self._machine)
        r.add_post("/api/write", self._write)
        r.add_post("/api/force", self._force)
        r.add_post("/api/analog", self._analog)
        r.add_post("/api/unforce", self._unforce)
        r.add_post("/api/control", self._control)
        r.add_get("/api/ws", self.pages.handle)
        r.add_get("/api/program", self._program)
        r.add_post("/api/program", self._program_change)
        r.add_get("/api/map", self._map)
        r.add_static("/static/", static_dir())
        return app

    async def start(self) -> None:
        await super().start()
        self.pages.start()

    async def close(self) -> None:
        await self.pages.close()
        await super().close()

    # -- plumbing ----------------------------------------------------------------------------
    @web.middleware
    async def _errors(self, request: web.Request, handler: Any) -> web.StreamResponse:
        """Every request: the guard's checks, then the route; a refusal is a 4xx with a
        JSON error and one (rate-limited) log line, never a traceback."""
        api = request.path.startswith("/api/")
        try:
            change = request.method == "POST" and request.path != "/api/read"
            query_token = self.guard.check(request, change)
            if request.method == "POST" and request.content_type != "application/json":
                raise ApiError("POST bodies are JSON: send Content-Type: application/json",
                               415)
            response = await handler(request)
            if query_token is not None and isinstance(response, web.Response | web.FileResponse):
                # the page opened with ?token=: its own requests and websocket carry it
                response.set_cookie(COOKIE, query_token, httponly=True, samesite="Strict")
            return response
        except ApiError as e:
            return self._refuse(request, e.status, str(e), api)
        except web.HTTPException as e:
            if e.status >= 400:
                return self._refuse(request, e.status, e.reason, api)
            raise

    def _refuse(self, request: web.Request, status: int, why: str, api: bool) -> web.Response:
        if status in (401, 403, 413, 415) or status == 400 and request.method == "POST":
            self.warn.warning(f"{status}", f"requests refused with {status}",
                              "web %s %s from %s refused (%d): %s", request.method,
                              request.path[:100], request.remote, status, why[:200])
        if api:
            return _json({"error": why}, status)
        return web.Response(text=why + "\n", status=status)

    @staticmethod
    async def _body(request: web.Request, limit: int = MAX_BODY) -> dict[str, Any]:
        too_big = ApiError(f"the request body is over {limit // 1024} KiB", 413)
        if (request.content_length or 0) > limit:
            raise too_big
        chunks, size = [], 0
        async for chunk in request.content.iter_any():  # chunked bodies are bounded too
            size += len(chunk)
            if size > limit:
                raise too_big
            chunks.append(chunk)
        try:
            data = json.loads(b"".join(chunks), parse_int=_json_int,
                              parse_constant=_json_constant)
        except BoundsError as e:
            raise ApiError(f"the request body: {e}") from None
        except (ValueError, UnicodeDecodeError, RecursionError):  # deep nesting too
            raise ApiError("the request body must be a JSON object") from None
        if not isinstance(data, dict):
            raise ApiError("the request body must be a JSON object")
        return data

    @staticmethod
    def _obj(data: dict[str, Any]) -> Any:
        if "object" not in data:
            raise ApiError('missing "object" (an address like "%MW3")')
        return data["object"]

    # -- endpoints ---------------------------------------------------------------------------
    async def _index(self, request: web.Request) -> web.StreamResponse:
        return web.FileResponse(static_dir() / "index.html")

    async def _info(self, request: web.Request) -> web.Response:
        info = self.ctl.info()
        info["token_required"] = self.token is not None
        info["update_hz"] = self.pages.update_hz
        info["version"] = self.ctl.port.program.info()
        info["symbols"] = self.ctl.port.program.symbols()
        return _json(info)

    async def _status(self, request: web.Request) -> web.Response:
        return _json(self.ctl.status() | {"web_clients": len(self.clients)})

    async def _read(self, request: web.Request) -> web.Response:
        if request.method == "POST":
            objs = (await self._body(request)).get("objects")
        else:
            objs = request.query.getall("obj", [])
        values = await self.ctl.port.read(objs)
        return _json({"values": values})

    async def _io(self, request: web.Request) -> web.Response:
        return _json(await self.ctl.io())

    async def _ladder(self, request: web.Request) -> web.Response:
        try:
            n = int(request.match_info["rung"])
        except ValueError:
            raise ApiError(f"rung {request.match_info['rung'][:20]!r}: a rung number") \
                from None
        svg = (await self.views.ladders({n}))[n]
        return web.Response(text=svg, content_type="image/svg+xml")

    async def _machine(self, request: web.Request) -> web.Response:
        try:
            since = int(request.query.get("since", "0"))
        except ValueError:
            raise ApiError("since: a sample number") from None
        status = await self.ctl.reading.sample(self.views.devices_now)
        return _json(self.views.machine_view(status, max(0, since)))

    async def _write(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        writes = data.get("writes", [data])
        if not isinstance(writes, list) or not writes:
            raise ApiError('"writes": a list of {"object": ..., "value": ...}')
        pairs = []
        for w in writes:
            if not isinstance(w, dict) or "value" not in w:
                raise ApiError('each write is {"object": "%MW3", "value": 5}')
            pairs.append((self._obj(w), w["value"]))
        done = self.ctl.port.write_many(pairs)
        return _json({"queued": done})

    async def _force(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        if "value" not in data:
            raise ApiError('missing "value"')
        return _json({"forced": self.ctl.port.force(self._obj(data), data["value"])})

    async def _unforce(self, request: web.Request) -> web.Response:
        data = await self._body(request) if request.can_read_body else {}
        return _json({"unforced": self.ctl.port.unforce(data.get("object"))})

    async def _control(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        return _json({"action": self.ctl.port.control(data.get("action"))})

    async def _analog(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        if "value" not in data:
            raise ApiError('missing "value": {"object": "%IW0.0", "value": 0.5}')
        force = data.get("force", False)
        if not isinstance(force, bool):
            raise ApiError(f'"force": true or false, not {force!r}')
        return _json(self.ctl.port.write_analog(self._obj(data), data["value"], force))

    async def _program(self, request: web.Request) -> web.Response:
        return _json(self.program.listing())

    async def _program_change(self, request: web.Request) -> web.Response:
        data = await self._body(request, MAX_PROGRAM_BODY)
        status, answer = await self.program.change(data)
        return _json(answer, status)

    async def _map(self, request: web.Request) -> web.Response:
        fmt = request.query.get("format", "json")
        if fmt == "csv":
            return web.Response(text=self.program.map_csv(), content_type="text/csv",
                                headers={"Content-Disposition":
                                         'attachment; filename="softplc-modbus-map.csv"'})
        if fmt != "json":
            raise ApiError(f"format {fmt[:20]!r}: json or csv")
        return _json(self.program.map_json())
