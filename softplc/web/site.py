"""Serving an aiohttp application on a TCP port: one way for every page's server (the
monitor, the replay page, the plant page)."""

from __future__ import annotations

from aiohttp import web

from softplc.modbus.server import format_address


async def serve(app: web.Application, host: str, port: int, *,
                reuse_address: bool | None = None) -> tuple[web.AppRunner, int]:
    """Start serving `app` on host:port; the runner (to clean up) and the real port (port 0
    asks the system for a free one)."""
    runner = web.AppRunner(app, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, host, port, reuse_address=reuse_address)
    await site.start()
    sock = site._server.sockets[0]  # type: ignore[union-attr]
    return runner, sock.getsockname()[1]


def http_url(host: str, port: int, path: str = "/") -> str:
    """The URL of host:port (an IPv6 address in brackets)."""
    return f"http://{format_address((host, port))}{path}"


class Site:
    """A page server on the caller's event loop: a subclass sets `app`, `host` and `port`
    (0: any free one, the real one once started)."""

    app: web.Application
    host: str
    port: int
    _runner: web.AppRunner | None = None

    async def start(self) -> None:
        self._runner, self.port = await serve(self.app, self.host, self.port,
                                              reuse_address=True)

    async def close(self) -> None:
        if self._runner is not None:
            await self._runner.cleanup()

    @property
    def url(self) -> str:
        return http_url(self.host, self.port)


__all__ = ["Site", "http_url", "serve"]
