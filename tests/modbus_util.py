"""A pymodbus `ModbusTcpServer` on its own event loop thread, on a free loopback port (the
independent Modbus server of the client tests)."""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pymodbus.server brings aiohttp (0.7 s): imported by the server's start
    from pymodbus.server import ModbusTcpServer
    from pymodbus.simulator import SimDevice


@contextmanager
def refused_port() -> Iterator[int]:
    """A loopback port where nothing listens, for the test's duration: held bound (not
    listening: a connection is refused), so that no other test, a parallel worker's, can
    take it meanwhile (a port found free and let go can be)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        yield s.getsockname()[1]


def closed_or_reply(sock: socket.socket, timeout: float = 2.0) -> bytes:
    """What the server does next: b"" if it closes or resets the connection, else the
    bytes it sends."""
    sock.settimeout(timeout)
    try:
        return sock.recv(1024)
    except ConnectionResetError:
        return b""


class PymodbusThread:
    """`with PymodbusThread() as s:` serves `self.device()` on 127.0.0.1:`s.port`."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.server: ModbusTcpServer | None = None
        self.port = 0
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)

    def device(self) -> SimDevice:
        raise NotImplementedError

    async def _start(self) -> int:
        from pymodbus.server import ModbusTcpServer

        self.server = ModbusTcpServer(self.device(), address=("127.0.0.1", 0))
        await self.server.serve_forever(background=True)
        return self.server.transport.sockets[0].getsockname()[1]

    def __enter__(self):
        self.thread.start()
        self.port = asyncio.run_coroutine_threadsafe(self._start(), self.loop).result(5)
        return self

    def __exit__(self, *exc) -> None:
        if self.server is not None:
            asyncio.run_coroutine_threadsafe(self.server.shutdown(), self.loop).result(5)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()
