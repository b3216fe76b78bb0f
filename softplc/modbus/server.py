"""Modbus TCP server: MBAP framing over asyncio, PDUs answered by `protocol.process_pdu`.

Why not pymodbus' server: in pymodbus 3.16 the datastore API is half-way through a
rewrite (`ModbusDeviceContext` is deprecated and its server context answers DEVICE_BUSY
for anything that is not a simulator context), its socket framer stalls on a non-zero
protocol id or an impossible length instead of dropping the client, and a request goes
through several layers of objects and a coroutine hop. The Twido map needs exact
exception codes, queued writes and snapshot reads; MBAP framing is 7 bytes, so the server
frames and decodes itself. pymodbus stays the reference client in the tests.

Framing errors (protocol id not 0, length field outside 2..254) close the connection:
the stream cannot be resynchronised. A frame left incomplete for `frame_timeout`
seconds, or a client silent for `idle_timeout` seconds, is closed too.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from struct import unpack_from
from typing import Any

from .image import ModbusImage
from .protocol import ExceptionCode, exception, pack_mbap, process_pdu

log = logging.getLogger("softplc.modbus")

MAX_PDU_LENGTH = 253  # MBAP length field = unit id + PDU <= 254


class ServerStats:
    """Counters read by the daemon's statistics line (plain ints: GIL-atomic updates)."""

    def __init__(self) -> None:
        self.requests = 0
        self.exceptions = 0
        self.connections = 0  # accepted since start
        self.rejected = 0  # refused: too many clients
        self.dropped = 0  # closed for a framing error or a timeout
        self.clients = 0  # connected now


class _Connection(asyncio.Protocol):
    def __init__(self, server: ModbusTcpServer):
        self.server = server
        self.image = server.image
        self.stats = server.stats
        self.buf = bytearray()
        self.transport: asyncio.Transport | None = None
        self.peer: Any = None
        self.last_rx = time.monotonic()
        self.partial_since: float | None = None
        self.paused = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.peer = transport.get_extra_info("peername")
        srv = self.server
        if len(srv.connections) >= srv.max_clients:
            self.stats.rejected += 1
            log.warning("refusing %s: %d clients already connected", self.peer, srv.max_clients)
            transport.abort()
            return
        srv.connections.add(self)
        self.stats.connections += 1
        self.stats.clients = len(srv.connections)
        log.info("client %s connected", self.peer)

    def connection_lost(self, exc: Exception | None) -> None:
        srv = self.server
        if self in srv.connections:
            srv.connections.discard(self)
            self.stats.clients = len(srv.connections)
            if self.buf:
                log.info("client %s left mid-frame (%d bytes dropped)", self.peer, len(self.buf))
            else:
                log.info("client %s disconnected", self.peer)

    # A client that pipelines requests without reading the replies: once its replies pass
    # the transport's high-water mark, stop decoding and reading until they drain, so
    # memory stays bounded (high-water mark + one read chunk).
    def pause_writing(self) -> None:
        self.paused = True
        if self.transport is not None:
            self.transport.pause_reading()

    def resume_writing(self) -> None:
        self.paused = False
        if self.transport is not None and not self.transport.is_closing():
            self.transport.resume_reading()
            self._process(time.monotonic())

    def drop(self, reason: str) -> None:
        log.warning("closing client %s: %s", self.peer, reason)
        self.stats.dropped += 1
        self.buf.clear()
        if self.transport is not None:
            self.transport.close()  # flushes responses already written

    def data_received(self, data: bytes) -> None:
        self.last_rx = now = time.monotonic()
        self.buf += data
        self._process(now)

    def _process(self, now: float) -> None:
        buf = self.buf
        img = self.image
        stats = self.stats
        write = self.transport.write  # type: ignore[union-attr]
        while len(buf) >= 7 and not self.paused:
            tid, pid, length, unit = unpack_from(">HHHB", buf)
            if pid != 0 or not 2 <= length <= MAX_PDU_LENGTH + 1:
                self.drop(f"bad MBAP header (protocol id {pid}, length {length})")
                return
            end = 6 + length
            if len(buf) < end:
                break
            pdu = bytes(buf[7:end])
            del buf[:end]
            try:
                resp = process_pdu(img, pdu)
            except Exception:  # a bug here must not kill the connection or the server
                log.exception("request %s failed", pdu.hex())
                resp = exception(pdu[0], ExceptionCode.SERVER_DEVICE_FAILURE)
            if resp[0] & 0x80:
                stats.exceptions += 1
            stats.requests += 1
            write(pack_mbap(tid, unit, resp))
        self.partial_since = now if buf else None


class ModbusTcpServer:
    """A Modbus TCP server over a `ModbusImage`. Start and stop it inside an event loop."""

    def __init__(self, image: ModbusImage, host: str = "127.0.0.1", port: int = 5020, *,
                 max_clients: int = 32, frame_timeout: float = 2.0,
                 idle_timeout: float | None = None):
        self.image = image
        self.host = host
        self.port = port
        self.max_clients = max_clients
        self.frame_timeout = frame_timeout
        self.idle_timeout = idle_timeout
        self.stats = ServerStats()
        self.connections: set[_Connection] = set()
        self._server: asyncio.base_events.Server | None = None
        self._sweeper: asyncio.Task | None = None

    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(
            lambda: _Connection(self), self.host, self.port, reuse_address=True)
        self.port = self._server.sockets[0].getsockname()[1]  # the real one if port was 0
        self._sweeper = asyncio.create_task(self._sweep())

    async def _sweep(self) -> None:
        """Close clients stuck mid-frame or silent for too long."""
        limits = [t for t in (self.frame_timeout, self.idle_timeout) if t]
        period = min([*limits, 1.0]) / 4
        while True:
            await asyncio.sleep(period)
            now = time.monotonic()
            for c in list(self.connections):
                if c.partial_since is not None and self.frame_timeout \
                        and now - c.partial_since > self.frame_timeout:
                    c.drop(f"incomplete frame for {self.frame_timeout:g} s")
                elif self.idle_timeout and now - c.last_rx > self.idle_timeout:
                    c.drop(f"silent for {self.idle_timeout:g} s")

    async def close(self) -> None:
        """Stop listening and close every client."""
        if self._sweeper is not None:
            self._sweeper.cancel()
        if self._server is not None:
            self._server.close()
        for c in list(self.connections):
            if c.transport is not None:
                c.transport.close()
        if self._server is not None:
            await self._server.wait_closed()
        await asyncio.sleep(0)  # let connection_lost callbacks run


class ServerThread:
    """Run a `ModbusTcpServer` on its own event loop in a background thread.

    The daemon keeps the main thread for the scan loop (precise sleeps, signals); tests
    and tools use this too.
    """

    def __init__(self, image: ModbusImage, host: str = "127.0.0.1", port: int = 5020,
                 **options: Any):
        self.server = ModbusTcpServer(image, host, port, **options)
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, name="modbus", daemon=True)
        self._ready = threading.Event()
        self._error: BaseException | None = None

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def stats(self) -> ServerStats:
        return self.server.stats

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_until_complete(self.server.start())
        except BaseException as e:  # e.g. address in use: reported by start()
            self._error = e
            self._ready.set()
            return
        self._ready.set()
        self.loop.run_forever()
        self.loop.run_until_complete(self.server.close())
        self.loop.close()

    def start(self) -> ServerThread:
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            raise self._error
        return self

    def stop(self, timeout: float = 5.0) -> None:
        if self._thread.is_alive():
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(timeout)

    def __enter__(self) -> ServerThread:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
