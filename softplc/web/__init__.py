"""The web monitor of a running softplc controller and its JSON/websocket API.

`control.Controller` is the API without HTTP over the access port (`softplc.access`:
checks, queued changes, scan-boundary reads);
`server.WebServer` serves it and the page (`static/`) with aiohttp on the daemon's asyncio
loop; `attach` is the daemon's hook. See docs/web.md.
"""

from __future__ import annotations

import asyncio
import secrets
from dataclasses import dataclass
from typing import Any

from softplc.access import AccessPort
from softplc.errors import SoftPLCError
from softplc.web.control import MAX_PAGES, ApiError, Controller
from softplc.web.security import is_loopback

DEFAULT_WEB_PORT = 8020  # beside Modbus' 5020; 0 = any free port


@dataclass
class WebOptions:
    port: int | None = DEFAULT_WEB_PORT  # None: no web monitor
    host: str = "127.0.0.1"
    read_only: bool = False
    token: str | None = None  # for changes; beyond loopback, for every request
    port_given: bool = True  # False: the default port, another free one if it is taken
    read_token: str | None = None  # beyond loopback: for reads only (no changes)
    allowed_hosts: tuple[str, ...] = ()  # Host names besides loopback's and addresses
    max_pages: int = MAX_PAGES  # websocket pages open at once


class WebHandle:
    """A web monitor started on a running event loop in another thread (the daemon's)."""

    def __init__(self, server: Any, controller: Controller, loop: asyncio.AbstractEventLoop,
                 note: str = ""):
        self.note = note
        self.server = server
        self.controller = controller
        self.loop = loop

    def banner(self) -> list[str]:
        s = self.server
        lines = [f"web monitor on {s.url}" + self.note +
                 (" (read-only)" if self.controller.read_only else "")]
        need = "every request" if not is_loopback(s.host) else "writes and forcing"
        if s.token is not None:
            lines.append(f"web token (needed for {need}): {s.token}  "
                         f"-> {s.url}?token={s.token}")
        return lines

    def stop(self, timeout: float = 5.0) -> None:
        fut = asyncio.run_coroutine_threadsafe(self.server.close(), self.loop)
        try:
            fut.result(timeout)
        except Exception:  # shutting down anyway
            pass
        self.controller.close()


def web_token(opt: WebOptions) -> str | None:
    """The full token: the given one, else a random one when the monitor listens beyond
    loopback (where every request needs a token), unless it is read-only with a read-only
    token; None: no token needed."""
    if opt.token is None and not is_loopback(opt.host) \
            and not (opt.read_only and opt.read_token):
        return secrets.token_urlsafe(16)
    return opt.token


def attach(daemon: Any, modbus: Any, port: AccessPort,
           opt: WebOptions | None) -> WebHandle | None:
    """The daemon's hook: serve the monitor on the Modbus server's event loop, over
    `port` (the controller's access port, with the Modbus image as its word lane), which
    it owns from then on (closed when the monitor stops or cannot start)."""
    if opt is None or opt.port is None:
        port.close()
        return None
    from softplc.web.server import WebServer

    token = web_token(opt)
    ctl = Controller(port, read_only=opt.read_only,
                     program_name=daemon.program_name,
                     status_extra=lambda: {"modbus_clients": modbus.stats.clients,
                                           "modbus_requests": modbus.stats.requests,
                                           "overruns": daemon.overruns,
                                           "late_starts": daemon.late_starts,
                                           "skipped_starts": daemon.skipped_starts,
                                           "jitter_max_ms": daemon.jitter_max * 1000})
    note = ""
    for tcp in (opt.port, 0):
        server = WebServer(ctl, opt.host, tcp, token=token, read_token=opt.read_token,
                           allowed_hosts=opt.allowed_hosts, max_pages=opt.max_pages)
        try:
            asyncio.run_coroutine_threadsafe(server.start(), modbus.loop).result(10)
            break
        except OSError as e:
            if opt.port_given or tcp == 0:
                ctl.close()
                raise SoftPLCError(f"web monitor: cannot listen on {opt.host}:{tcp}: "
                                   f"{e.strerror or e}") from None
            note = f" (port {opt.port} is taken)"
    return WebHandle(server, ctl, modbus.loop, note)


__all__ = ["DEFAULT_WEB_PORT", "MAX_PAGES", "ApiError", "Controller", "WebHandle", "WebOptions",
           "attach", "is_loopback", "web_token"]
