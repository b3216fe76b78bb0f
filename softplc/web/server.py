"""The web monitor's HTTP/websocket server (aiohttp), on the daemon's asyncio loop.

    GET  /                    the monitor page (static files shipped in softplc/web/static)
    GET  /api/info            program, controller, modules, devices, rungs, read-only flag
    GET  /api/status          state, scan times, overruns, Modbus clients, forced objects
    GET  /api/read?obj=%MW0:4&obj=%TM0      values of one scan
    GET  /api/io              every I/O channel: value, forced, driving device
    GET  /api/ladder/N        rung N as live SVG
    GET  /api/machine?since=K simulated devices and the trace recorder's samples from K
    POST /api/write   {"object": "%MW3", "value": 5} or {"writes": [{...}, ...]}
    POST /api/force   {"object": "%I0.1", "value": 1}
    POST /api/unforce {"object": "%I0.1"} (no object: all)
    POST /api/control {"action": "run" | "stop" | "cold" | "warm"}
    GET  /api/ws              websocket: send {"subscribe": {...}}, receive updates

Errors are JSON `{"error": "..."}` with status 400 (bad request), 401 (token missing or
wrong), 403 (not writable, read-only monitor, another site's page), 404 or 415 (a POST
body that is not JSON). When a token is set, every POST
needs `Authorization: Bearer TOKEN` (or `?token=TOKEN`).
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import math
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from aiohttp import WSMsgType, web

from ..address import Ref
from . import ladderview
from .control import MAX_OBJECTS, ApiError, Controller

log = logging.getLogger("softplc.web")

UPDATE_HZ = 10.0  # websocket updates per second (the issue asks for >= 10)
MAX_LIVE_RUNGS = 8  # rungs one page may watch live at a time
TRACE_CHUNK = 5000  # trace samples per update at most: a new page catches up over a few
MAX_BODY = 64 * 1024


def static_dir() -> Path:
    return Path(str(resources.files("softplc.web") / "static"))


def _json(data: Any, status: int = 200) -> web.Response:
    return web.Response(text=json.dumps(_clean(data), allow_nan=False, default=str),
                        status=status, content_type="application/json")


def _clean(v: Any) -> Any:
    """NaN and infinities (a float word can hold them) as strings: JSON has no such numbers."""
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_clean(x) for x in v]
    return v


class _Client:
    """One websocket page and what it asked for."""

    def __init__(self, ws: web.WebSocketResponse):
        self.ws = ws
        self.objects: list[tuple[str, Ref]] = []
        self.io = False
        self.rungs: list[int] = []
        self.svg_sent: dict[int, str] = {}
        self.machine = False
        self.trace_sent = 0


class WebServer:
    def __init__(self, controller: Controller, host: str = "127.0.0.1", port: int = 8020, *,
                 token: str | None = None, update_hz: float = UPDATE_HZ):
        self.ctl = controller
        self.host = host
        self.port = port
        self.token = token
        self.update_hz = update_hz
        self.clients: set[_Client] = set()
        self.updates_sent = 0
        self._runner: web.AppRunner | None = None
        self._ticker: asyncio.Task | None = None
        self._rung_refs: dict[tuple[int, int], list[Ref]] = {}
        self._svg_cache: dict[Any, str] = {}
        self.app = self._make_app()

    # -- set-up ------------------------------------------------------------------------------
    def _make_app(self) -> web.Application:
        app = web.Application(middlewares=[self._errors], client_max_size=MAX_BODY)
        r = app.router
        r.add_get("/", self._index)
        r.add_get("/api/info", self._info)
        r.add_get("/api/status", self._status)
        r.add_get("/api/read", self._read)
        r.add_post("/api/read", self._read)
        r.add_get("/api/io", self._io)
        r.add_get("/api/ladder/{rung}", self._ladder)
        r.add_get("/api/machine", self._machine)
        r.add_post("/api/write", self._write)
        r.add_post("/api/force", self._force)
        r.add_post("/api/analog", self._analog)
        r.add_post("/api/unforce", self._unforce)
        r.add_post("/api/control", self._control)
        r.add_get("/api/ws", self._ws)
        r.add_static("/static/", static_dir())
        return app

    async def start(self) -> None:
        self._runner = web.AppRunner(self.app, access_log=None)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port, reuse_address=True)
        await site.start()
        sock = site._server.sockets[0]  # type: ignore[union-attr]
        self.port = sock.getsockname()[1]  # the real one if port was 0
        self._ticker = asyncio.create_task(self._tick_loop())

    async def close(self) -> None:
        if self._ticker is not None:
            self._ticker.cancel()
        for c in list(self.clients):
            await c.ws.close()
        if self._runner is not None:
            await self._runner.cleanup()

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    # -- plumbing ----------------------------------------------------------------------------
    @web.middleware
    async def _errors(self, request: web.Request, handler: Any) -> web.StreamResponse:
        try:
            if request.path.startswith("/api/"):
                self._check_origin(request)
            if request.method == "POST":
                if request.content_type != "application/json":
                    raise ApiError("POST bodies are JSON: send Content-Type: application/json",
                                   415)
                if request.path != "/api/read":
                    self._check_token(request)
            return await handler(request)
        except ApiError as e:
            return _json({"error": str(e)}, e.status)
        except web.HTTPException as e:
            if e.status >= 400 and request.path.startswith("/api/"):
                return _json({"error": e.reason}, e.status)
            raise

    @staticmethod
    def _check_origin(request: web.Request) -> None:
        """Another web site's page in the user's browser must not drive the PLC (or read it
        over the websocket): a browser names the page's origin, which must be this server.
        JSON-only POST bodies make its cross-site requests preflighted, which fail too."""
        origin = request.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc != request.host:
            raise ApiError(f"requests from the page of {origin} are refused", 403)

    def _check_token(self, request: web.Request) -> None:
        if self.token is None:
            return
        given = request.headers.get("Authorization", "").removeprefix("Bearer ").strip() \
            or request.query.get("token", "")
        if not given:
            raise ApiError("this monitor needs a token for changes: send "
                           "'Authorization: Bearer TOKEN' (printed when the daemon started)",
                           401)
        if not hmac.compare_digest(given, self.token):
            raise ApiError("wrong token", 401)

    @staticmethod
    async def _body(request: web.Request) -> dict[str, Any]:
        try:
            data = await request.json()
        except (json.JSONDecodeError, UnicodeDecodeError, ValueError):
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
        info["update_hz"] = self.update_hz
        return _json(info)

    async def _status(self, request: web.Request) -> web.Response:
        return _json(self.ctl.status() | {"web_clients": len(self.clients)})

    async def _read(self, request: web.Request) -> web.Response:
        if request.method == "POST":
            objs = (await self._body(request)).get("objects")
        else:
            objs = request.query.getall("obj", [])
        values = await self.ctl.read(objs)
        return _json({"values": values})

    async def _io(self, request: web.Request) -> web.Response:
        refs = self.ctl.io_refs()
        read_io, read_analog = self.ctl.values_fn(refs), self.ctl.analog_values_fn()
        values, analog = await self.ctl.sample(lambda: (read_io(), read_analog()))
        forced = self.ctl.plc.forced
        return _json({"modules": self.ctl.io_layout(),
                      "io": {name: {"value": v, "forced": name in forced,
                                    "driven_by": self.ctl.device_io.get(name, "")}
                             for name, v in values.items()},
                      "analog": {ch["address"]: ch | analog[ch["address"]]
                                 | {"forced": ch["address"] in forced}
                                 for ch in self.ctl.analog_channels()}})

    async def _ladder(self, request: web.Request) -> web.Response:
        try:
            n = int(request.match_info["rung"])
        except ValueError:
            raise ApiError(f"rung {request.match_info['rung']!r}: a rung number") from None
        svg = (await self._ladders({n}))[n]
        return web.Response(text=svg, content_type="image/svg+xml")

    async def _machine(self, request: web.Request) -> web.Response:
        try:
            since = int(request.query.get("since", "0"))
        except ValueError:
            raise ApiError("since: a sample number") from None
        status = await self.ctl.sample(self._devices_now)
        return _json(self._machine_view(status, max(0, since)))

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
        done = self.ctl.write_many(pairs)
        return _json({"queued": done})

    async def _force(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        if "value" not in data:
            raise ApiError('missing "value"')
        return _json({"forced": self.ctl.force(self._obj(data), data["value"])})

    async def _unforce(self, request: web.Request) -> web.Response:
        data = await self._body(request) if request.can_read_body else {}
        return _json({"unforced": self.ctl.unforce(data.get("object"))})

    async def _control(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        return _json({"action": self.ctl.control(data.get("action"))})

    # -- live views --------------------------------------------------------------------------
    def _refs_of(self, n: int) -> list[Ref]:
        plc = self.ctl.plc
        rungs = plc.rungs
        if not 0 <= n < len(rungs):
            raise ApiError(f"rung {n}: the program has rungs 0..{len(rungs) - 1}", 404)
        key = (plc.program_version, n)
        refs = self._rung_refs.get(key)
        if refs is None:
            refs = self._rung_refs[key] = ladderview.refs(rungs[n])
        return refs

    async def _ladders(self, wanted: set[int]) -> dict[int, str]:
        refs = {n: self._refs_of(n) for n in wanted}
        readers = {n: self.ctl.reader(r) for n, r in refs.items()}
        raw = await self.ctl.sample(lambda: {n: read() for n, read in readers.items()})
        return {n: self._svg(n, ladderview.capture(refs[n], raw[n])) for n in wanted}

    def _svg(self, n: int, values: dict[Ref, Any]) -> str:
        plc = self.ctl.plc
        forced = set(plc.forced)
        key = (plc.program_version, n, repr(sorted(values.items(), key=lambda kv: str(kv[0]))),
               tuple(sorted(forced)))
        svg = self._svg_cache.get(key)
        if svg is None:
            if len(self._svg_cache) > 256:
                self._svg_cache.clear()
            svg = self._svg_cache[key] = ladderview.render(plc.rungs[n], values, forced)
        return svg

    def _devices_now(self) -> dict[str, Any]:
        out = {}
        for name, dev in self.ctl.plc.devices.items():
            st = dict(dev.status())
            st["type"] = getattr(dev, "type_name", "device")
            for attr in ("travel", "steps_per_unit"):
                if hasattr(dev, attr):
                    st[attr] = getattr(dev, attr)
            out[name] = st
        return out

    def _machine_view(self, devices: dict[str, Any], since: int) -> dict[str, Any]:
        trace = self.ctl.plc.trace
        n = len(trace)
        chunk = [list(s) for s in trace[since:min(n, since + TRACE_CHUNK)]]
        return {"devices": devices, "trace_from": since, "trace": chunk,
                "trace_total": n}

    # -- websocket ---------------------------------------------------------------------------
    async def _analog(self, request: web.Request) -> web.Response:
        data = await self._body(request)
        if "value" not in data:
            raise ApiError('missing "value": {"object": "%IW0.0", "value": 0.5}')
        force = data.get("force", False)
        if not isinstance(force, bool):
            raise ApiError(f'"force": true or false, not {force!r}')
        return _json(self.ctl.write_analog(self._obj(data), data["value"], force))

    async def _ws(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=30)
        await ws.prepare(request)
        client = _Client(ws)
        self.clients.add(client)
        try:
            async for msg in ws:
                if msg.type != WSMsgType.TEXT:
                    continue
                try:
                    self._subscribe(client, json.loads(msg.data))
                except (ApiError, ValueError) as e:
                    await ws.send_str(json.dumps({"type": "error", "error": str(e)}))
        finally:
            self.clients.discard(client)
        return ws

    def _subscribe(self, client: _Client, msg: Any) -> None:
        sub = msg.get("subscribe") if isinstance(msg, dict) else None
        if not isinstance(sub, dict):
            raise ApiError('expected {"subscribe": {"objects": [...], "io": true, '
                           '"rungs": [N, ...], "machine": true}}')
        if "objects" in sub:
            objs = sub["objects"] or []
            if not isinstance(objs, list):
                raise ApiError("objects: a list of addresses")
            good, bad = [], []
            for o in objs:
                try:
                    good += [(str(r), r) for r in self.ctl.resolve(o)]
                except ApiError as e:
                    bad.append(str(e))
            if len(good) > MAX_OBJECTS:
                raise ApiError(f"{len(good)} objects: at most {MAX_OBJECTS} per page")
            client.objects = good
            if bad:
                raise ApiError("; ".join(bad))
        if "io" in sub:
            client.io = bool(sub["io"])
        if "rungs" in sub:
            rungs = sub["rungs"] or []
            if not isinstance(rungs, list) or len(rungs) > MAX_LIVE_RUNGS or not all(
                    isinstance(n, int) and not isinstance(n, bool) for n in rungs):
                raise ApiError(f"rungs: a list of at most {MAX_LIVE_RUNGS} rung numbers")
            for n in rungs:
                self._refs_of(n)
            client.rungs = rungs
            client.svg_sent = {}
        if "machine" in sub:
            client.machine = bool(sub["machine"])
            client.trace_sent = 0

    async def _tick_loop(self) -> None:
        period = 1.0 / self.update_hz
        loop = asyncio.get_running_loop()
        next_t = loop.time()
        while True:
            next_t += period
            try:
                if self.clients:
                    await self._tick()
            except Exception:  # a bug here must not end the updates of every page
                log.exception("web update failed")
            await asyncio.sleep(max(0.0, next_t - loop.time()))
            if loop.time() - next_t > period:  # fell behind: do not burst to catch up
                next_t = loop.time()

    async def _tick(self) -> None:
        ctl = self.ctl
        clients = list(self.clients)
        objs = {name: ref for c in clients for name, ref in c.objects}
        io = ctl.io_refs() if any(c.io for c in clients) else []
        rungs = {n for c in clients for n in c.rungs}
        rung_refs = {n: self._refs_of(n) for n in rungs if n < len(ctl.plc.rungs)}
        machine = any(c.machine for c in clients)
        # prepared here, run in the scan thread: there, only the reads themselves
        read_values, read_io = ctl.values_fn(list(objs.items())), ctl.values_fn(io)
        read_analog = ctl.analog_values_fn() if io else dict
        read_rungs = {n: ctl.reader(r) for n, r in rung_refs.items()}

        def take() -> dict[str, Any]:
            return {"values": read_values(), "io": read_io(), "analog": read_analog(),
                    "ladder": {n: read() for n, read in read_rungs.items()},
                    "devices": self._devices_now() if machine else {},
                    "status": ctl.status()}

        snap = await ctl.sample(take)
        snap["ladder"] = {n: ladderview.capture(rung_refs[n], v)
                          for n, v in snap["ladder"].items()}
        status = _clean(snap["status"] | {"web_clients": len(clients)})
        values = _clean(snap["values"])
        for c in clients:
            msg: dict[str, Any] = {"type": "update", "status": status}
            if c.objects:
                msg["values"] = {name: values.get(name) for name, _ in c.objects}
            if c.io:
                msg["io"] = snap["io"]
                msg["analog"] = snap["analog"]
                msg["device_io"] = ctl.device_io
            changed = {}
            for n in c.rungs:
                if n in snap["ladder"]:
                    svg = self._svg(n, snap["ladder"][n])
                    if c.svg_sent.get(n) is not svg:
                        changed[n] = c.svg_sent[n] = svg
            if changed:
                msg["ladder"] = changed
            if c.machine:
                view = self._machine_view(snap["devices"], c.trace_sent)
                c.trace_sent = view["trace_from"] + len(view["trace"])
                msg["machine"] = _clean(view)
            if c.ws.closed:
                continue
            try:
                await c.ws.send_str(json.dumps(msg))
                self.updates_sent += 1
            except (ConnectionError, RuntimeError):
                self.clients.discard(c)
