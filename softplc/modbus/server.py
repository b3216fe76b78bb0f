"""Modbus TCP server: MBAP framing over asyncio, PDUs answered by `protocol.process_pdu`.

Why not pymodbus' server: in pymodbus 3.16 the datastore API is half-way through a
rewrite (`ModbusDeviceContext` is deprecated and its server context answers DEVICE_BUSY
for anything that is not a simulator context), its socket framer stalls on a non-zero
protocol id or an impossible length instead of dropping the client, and a request goes
through several layers of objects and a coroutine hop. The Twido map needs exact
exception codes, queued writes and snapshot reads; MBAP framing is 7 bytes, so the server
frames and decodes itself. pymodbus stays the reference client in the tests.

Framing errors (protocol id not 0, length field outside 2..254) close the connection:
the stream cannot be resynchronised. Slots are kept for clients that use them (issue 21):

- a frame has `frame_timeout` seconds from its first byte to its last (later bytes do
  not restart the timer: a client dripping one byte a second is closed);
- a client that completes no request for `idle_timeout` seconds (60 by default; 0 =
  never) is closed: bytes of an unfinished frame are not activity;
- a client whose replies pile up unread (the transport's write buffer past
  `WRITE_BUFFER_LIMIT`, i.e. the kernel's socket buffers are full too) is reset at once;
- accepted sockets have TCP keepalive (a peer that vanished is found within ~1 min);
- when every slot is taken, a new client takes the slot of a connection that is not
  being used (the Modbus messaging implementation guide's "close the oldest unused
  connection"): first one that leaves over `UNREAD_EVICT` bytes of replies unread,
  then one that has completed no request `EVICT_GRACE` s after connecting (oldest
  first), then one idle for `EVICT_IDLE` s (longest idle first); see
  `ModbusTcpServer._evictee`. With none of those the newcomer is reset as before, so a
  connection storm cannot push out clients that poll.

Connections are accepted by the server itself: one from an address outside the allow
list, or past the client limit, is reset right after `accept()`, before a byte is read
or any asyncio object exists for it (see `ModbusTcpServer`). Warnings a client can
repeat at will go through `RateLimitedLog`: one per kind per 10 s, then a count.
"""

from __future__ import annotations

import asyncio
import errno
import fcntl
import ipaddress
import logging
import os
import socket
import termios
import threading
import time
from collections.abc import Callable, Iterable
from struct import pack, unpack_from
from typing import Any, cast

from softplc.errors import SoftPLCError
from softplc.modbus.image import ModbusImage
from softplc.modbus.protocol import ExceptionCode, exception, process_pdu
from softplc.modbus_codec import GOOD_LENGTHS, MBAP_SIZE, PROTOCOL_MODBUS, bad_header, frame, header

log = logging.getLogger("softplc.modbus")

IPNetwork = ipaddress.IPv4Network | ipaddress.IPv6Network
LISTEN_BACKLOG = 128
ACCEPT_BATCH = 16  # connections accepted per event-loop turn
ACCEPT_PAUSE = 0.1  # seconds without accepting after accept() fails (e.g. out of fds)
# After a batch with refusals, stop accepting for this long: the kernel holds the rest in
# the listen backlog, so a storm costs at most ACCEPT_BATCH refusals per pause of CPU
# (and of GIL time the scan thread might wait for), however many clients storm.
REFUSE_PAUSE = 0.010
LOG_INTERVAL = 10.0  # seconds: at most one warning of a kind per interval, then a summary
DEFAULT_IDLE_TIMEOUT = 60.0  # seconds without a complete request (HMIs poll far faster)
# Unread replies the server buffers for one client before resetting it. The kernel's
# socket buffers (hundreds of kB on each side) fill first, so a client that reads its
# replies, even pipelining, never gets near it.
WRITE_BUFFER_LIMIT = 64 * 1024
CLOSE_GRACE = 1.0  # seconds a closed connection may take to flush before it is reset
# Eviction (table full). A client that reads its replies has at most a few unacknowledged
# on the wire; 8 kB is 30 full-size replies.
UNREAD_EVICT = 8 * 1024
EVICT_GRACE = 0.5  # seconds a new connection has to complete its first request
EVICT_IDLE = 5.0  # seconds without a request before a client's slot may be given away
# TCP keepalive: first probe after 30 s of silence, then every 10 s, 3 unanswered = dead
KEEPALIVE = (("TCP_KEEPIDLE", 30), ("TCP_KEEPINTVL", 10), ("TCP_KEEPCNT", 3))
_LINGER_RESET = pack("ii", 1, 0)  # SO_LINGER on, 0 s: close() sends an RST
_monotonic = time.monotonic
_OUTQ = getattr(termios, "TIOCOUTQ", None)  # = SIOCOUTQ on Linux: unacknowledged bytes


class ServerStats:
    """Counters read by the daemon's statistics line (plain ints: GIL-atomic updates)."""

    def __init__(self) -> None:
        self.requests = 0
        self.exceptions = 0
        self.connections = 0  # accepted since start
        self.rejected = 0  # refused: too many clients
        self.denied = 0  # refused: address not in the allow list
        self.dropped = 0  # closed for a framing error, a timeout or unread replies
        self.evicted = 0  # reset to make room for a new client (table full)
        self.clients = 0  # connected now


class RateLimitedLog:
    """Warnings that may repeat as fast as a client can loop (refused connections, bad
    headers): the first of each kind in an interval is logged, the others are counted and
    summarised in one line when the interval is over ("... 1234 more in the last 10 s")."""

    def __init__(self, logger: logging.Logger, interval: float = 10.0,
                 clock: Callable[[], float] = time.monotonic):
        self.log = logger
        self.interval = interval
        self.clock = clock
        self._kinds: dict[str, list[Any]] = {}  # kind -> [interval end, suppressed, label]

    def warning(self, kind: str, label: str, msg: str, *args: Any) -> None:
        """Log `msg` unless a `kind` warning was logged less than `interval` ago."""
        now = self.clock()
        st = self._kinds.get(kind)
        if st is not None and now < st[0]:
            st[1] += 1
            return
        if st is not None:
            self._summarise(st)
        self.log.warning(msg, *args)
        self._kinds[kind] = [now + self.interval, 0, label]

    def _summarise(self, st: list[Any]) -> None:
        if st[1]:
            self.log.warning("%d more %s in the last %g s", st[1], st[2], self.interval)
            st[1] = 0

    def flush(self, force: bool = False) -> None:
        """Summarise the kinds whose interval is over (all of them if `force`)."""
        now = self.clock()
        for kind, st in list(self._kinds.items()):
            if force or now >= st[0]:
                self._summarise(st)
                if now >= st[0]:
                    del self._kinds[kind]


def listen_addresses(host: str) -> list[str]:
    """The addresses to bind for `host`: "localhost" is both loopbacks, 127.0.0.1 and ::1;
    a name resolves to each of its addresses."""
    if host == "localhost":
        return ["127.0.0.1", "::1"]
    try:
        infos = socket.getaddrinfo(host or None, None, type=socket.SOCK_STREAM,
                                   flags=socket.AI_PASSIVE)
    except socket.gaierror as e:
        raise OSError(e.errno, f"unknown host {host!r} ({e.strerror})") from None
    return list(dict.fromkeys(str(info[4][0]) for info in infos))


def bind_listeners(host: str, port: int, backlog: int = LISTEN_BACKLOG) -> list[socket.socket]:
    """Bound, listening, non-blocking sockets for `host`:`port` (0: one free port for all).
    Binding happens before anything else at start-up. ::1 is skipped for "localhost"
    on a machine without IPv6 loopback."""
    socks: list[socket.socket] = []
    try:
        for addr in listen_addresses(host):
            family = socket.AF_INET6 if ":" in addr else socket.AF_INET
            try:
                s = socket.socket(family, socket.SOCK_STREAM)
            except OSError:
                if host == "localhost" and family == socket.AF_INET6:
                    continue
                raise
            socks.append(s)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6:
                s.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            try:
                s.bind((addr, port))
            except OSError as e:
                if host == "localhost" and family == socket.AF_INET6 and e.errno in (
                        errno.EADDRNOTAVAIL, errno.EAFNOSUPPORT):
                    socks.pop().close()
                    continue
                raise
            port = s.getsockname()[1]
            s.listen(backlog)
            s.setblocking(False)
    except BaseException:
        for s in socks:
            s.close()
        raise
    if not socks:
        raise OSError(errno.EADDRNOTAVAIL, f"no address to listen on for {host!r}")
    return socks


def format_address(sockname: Any) -> str:
    host, port = sockname[0], sockname[1]
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def parse_allow(entries: Iterable[str]) -> tuple[IPNetwork, ...]:
    """`--allow` entries (addresses or networks, IPv4 or IPv6) -> networks."""
    nets = []
    for e in entries:
        try:
            nets.append(ipaddress.ip_network(str(e).strip(), strict=False))
        except ValueError:
            raise SoftPLCError(f"--allow {e!r}: not an IP address or network "
                               f"(e.g. 192.168.1.0/24, 10.0.0.5, ::1)") from None
    return tuple(nets)


class _Connection(asyncio.Protocol):
    def __init__(self, server: ModbusTcpServer):
        self.server = server
        self.image = server.image
        self.stats = server.stats
        self.buf = bytearray()
        self.transport: asyncio.Transport | None = None
        self.peer: Any = None
        # monotonic time of the last complete request (the connection's start before one)
        self.last_request = time.monotonic()
        self.served = False  # at least one request completed
        self.partial_since: float | None = None  # first byte of the unfinished frame
        self.paused = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # uvloop's transports are not asyncio.Transport subclasses but have its methods
        self.transport = transport = cast(asyncio.Transport, transport)
        transport.set_write_buffer_limits(high=WRITE_BUFFER_LIMIT)
        self.peer = transport.get_extra_info("peername")
        srv = self.server
        srv.connections.add(self)
        sock = transport.get_extra_info("socket")
        if sock is not None:
            srv._adopting.discard(sock.fileno())  # counted once, as a connection now
        self.stats.connections += 1
        self.stats.clients = len(srv.connections)
        log.info("client %s connected", self.peer)

    def connection_lost(self, exc: Exception | None) -> None:
        srv = self.server
        srv.closing.discard(self)
        if self in srv.connections:
            srv.connections.discard(self)
            self.stats.clients = len(srv.connections)
            if self.buf:
                log.info("client %s left mid-frame (%d bytes dropped)", self.peer, len(self.buf))
            else:
                log.info("client %s disconnected", self.peer)

    # A client that pipelines requests without reading the replies: once the kernel's
    # buffers and then ours pass the high-water mark, it is reset (its slot freed, memory
    # bounded by the mark plus one read chunk); its replies cannot be delivered anyway.
    def pause_writing(self) -> None:
        self.paused = True
        self.drop("unread", "clients reset for unread replies",
                  f"{WRITE_BUFFER_LIMIT // 1024} kB of replies not read", reset=True)

    def resume_writing(self) -> None:  # not reached: pause_writing resets the connection
        self.paused = False

    def drop(self, kind: str, label: str, reason: str, reset: bool = False) -> None:
        """Close the connection and free its slot at once. `reset`: an RST, discarding
        unsent replies; else the replies already written are flushed first (for at most
        CLOSE_GRACE s: a client that does not read them is reset then)."""
        self.server.warn.warning(kind, label, "closing client %s: %s", self.peer, reason)
        self.stats.dropped += 1
        self.release(reset)

    def release(self, reset: bool) -> None:
        srv = self.server
        self.buf.clear()
        if self in srv.connections:
            srv.connections.discard(self)
            srv.closing.add(self)
            self.stats.clients = len(srv.connections)
        tr = self.transport
        if tr is None:
            return
        if reset:
            tr.abort()
            return
        tr.close()  # flushes the replies already written
        if tr.get_write_buffer_size() and srv._loop is not None:
            srv._loop.call_later(CLOSE_GRACE, tr.abort)

    def unread(self) -> int:
        """Bytes of replies the client has not taken: the kernel's send queue (sent but
        not acknowledged: the client's receive buffer is full) plus ours."""
        tr = self.transport
        if tr is None:
            return 0
        queued = tr.get_write_buffer_size()
        sock = tr.get_extra_info("socket")
        if _OUTQ is not None and sock is not None:
            try:
                queued += unpack_from("i", fcntl.ioctl(sock.fileno(), _OUTQ, b"\0\0\0\0"))[0]
            except OSError:
                pass
        return queued

    def data_received(self, data: bytes) -> None:
        now = _monotonic()
        if self.buf:
            self.buf += data
            self._process(now, self.buf)
            return
        # Usually a whole request (or several): parsed straight from `data`, without
        # copying it into the buffer first; what follows the last whole frame is kept.
        self.partial_since = now  # a frame starts: its deadline runs from now
        pos = self._process(now, data)
        if pos < len(data) and self.transport is not None and not self.paused:
            self.buf += data[pos:]

    def _process(self, now: float, buf: bytes | bytearray) -> int:
        """Answer the whole frames in `buf` (the connection's buffer, whose answered
        frames are deleted, or the bytes just received); returns the offset answered."""
        img = self.image
        stats = self.stats
        write = self.transport.write  # type: ignore[union-attr]
        done = False
        pos = 0
        size = len(buf)
        while size - pos >= MBAP_SIZE and not self.paused:
            tid, pid, length, unit = header(buf, pos)
            if pid != PROTOCOL_MODBUS or length not in GOOD_LENGTHS:  # (bad_header, inline)
                self.drop("header", "clients closed for a bad MBAP header",
                          str(bad_header(pid, length)))
                return size
            end = pos + MBAP_SIZE - 1 + length
            if size < end:
                break
            pdu = bytes(buf[pos + MBAP_SIZE:end])
            pos = end
            done = True
            try:
                resp = process_pdu(img, pdu)
            except Exception:  # a bug here must not kill the connection or the server
                log.exception("request %s failed", pdu.hex())
                resp = exception(pdu[0], ExceptionCode.SERVER_DEVICE_FAILURE)
            if resp[0] & 0x80:
                stats.exceptions += 1
            stats.requests += 1
            write(frame(tid, unit, resp))
        if buf is self.buf and pos:
            del buf[:pos]
            size -= pos
            pos = 0
        if done:
            self.last_request = now
            self.served = True
            # what follows the last complete frame arrived now: a new frame's first bytes
            self.partial_since = now if size > pos else None
        elif size == pos:
            self.partial_since = None
        return pos


class ModbusTcpServer:
    """A Modbus TCP server over a `ModbusImage`. Start and stop it inside an event loop.

    Connections are accepted by the server itself, not by `loop.create_server`: one that
    is refused (address not allowed, client limit reached) is reset right after
    `accept()`, before any byte is read and before asyncio builds a transport and a
    protocol for it, so a connection storm costs a few microseconds per attempt.
    """

    def __init__(self, image: ModbusImage, host: str = "127.0.0.1", port: int = 5020, *,
                 max_clients: int = 32, frame_timeout: float = 2.0,
                 idle_timeout: float | None = DEFAULT_IDLE_TIMEOUT,
                 sockets: list[socket.socket] | None = None,
                 allow: tuple[IPNetwork, ...] | None = None,
                 log_interval: float = LOG_INTERVAL):
        self.image = image
        self.host = host
        self.port = port
        self.max_clients = max_clients
        self.frame_timeout = frame_timeout
        self.idle_timeout = idle_timeout
        self.allow = allow  # None: any address
        self.sockets = sockets or []
        self.stats = ServerStats()
        self.warn = RateLimitedLog(log, log_interval)
        self.connections: set[_Connection] = set()  # the slots taken
        self.closing: set[_Connection] = set()  # dropped, flushing their last replies
        self._adopting: set[int] = set()  # fds accepted, transport being built
        self._loop: asyncio.AbstractEventLoop | None = None
        self._sweeper: asyncio.Task | None = None
        self._allowed_cache: dict[str, bool] = {}

    @property
    def addresses(self) -> list[str]:
        return [format_address(s.getsockname()) for s in self.sockets]

    async def start(self) -> None:
        loop = self._loop = asyncio.get_running_loop()
        if not self.sockets:
            self.sockets = bind_listeners(self.host, self.port)
        self.port = self.sockets[0].getsockname()[1]  # the real one if port was 0
        for s in self.sockets:
            loop.add_reader(s.fileno(), self._accept, s)
        self._sweeper = asyncio.create_task(self._sweep())

    def _allowed(self, host: str) -> bool:
        ok = self._allowed_cache.get(host)
        if ok is None:
            ip = ipaddress.ip_address(host.split("%", 1)[0])
            if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
                ip = ip.ipv4_mapped
            ok = any(ip in net for net in self.allow or ())
            if len(self._allowed_cache) > 4096:
                self._allowed_cache.clear()
            self._allowed_cache[host] = ok
        return ok

    def _pause_accepting(self, lsock: socket.socket, seconds: float) -> None:
        loop = self._loop
        assert loop is not None
        loop.remove_reader(lsock.fileno())
        loop.call_later(seconds, self._resume_accepting, lsock)

    def _resume_accepting(self, lsock: socket.socket) -> None:
        if self._loop is not None and lsock.fileno() >= 0:
            self._loop.add_reader(lsock.fileno(), self._accept, lsock)

    def _accept(self, lsock: socket.socket) -> None:
        """Accept what is waiting (a bounded batch, so the loop stays fair)."""
        loop = self._loop
        assert loop is not None
        refused = False
        for _ in range(ACCEPT_BATCH):
            try:
                conn, peer = lsock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as e:  # e.g. EMFILE: pause accepting instead of spinning
                self.warn.warning("accept", "failed accepts", "accept failed: %s", e)
                self._pause_accepting(lsock, ACCEPT_PAUSE)
                return
            if self.allow is not None and not self._allowed(peer[0]):
                self.stats.denied += 1
                self.warn.warning("deny", "connections refused (not in --allow)",
                                  "refusing %s: address not in the allow list", peer[0])
                _reset(conn)
                refused = True
            elif (len(self.connections) + len(self._adopting) >= self.max_clients
                  and not self._evict(peer[0])):
                self.stats.rejected += 1
                self.warn.warning("limit", "connections refused (client limit)",
                                  "refusing %s: %d clients already connected", peer[0],
                                  self.max_clients)
                _reset(conn)
                refused = True
            else:
                self._adopting.add(conn.fileno())
                loop.create_task(self._adopt(conn))
        if refused:
            self._pause_accepting(lsock, REFUSE_PAUSE)

    def _evictee(self) -> tuple[_Connection, str] | None:
        """The connection whose slot a new client takes when the table is full, and why;
        None when every connection is in use (see the module docstring)."""
        now = time.monotonic()
        unread = max(((c.unread(), c) for c in self.connections), key=lambda u: u[0],
                     default=(0, None))
        if unread[1] is not None and unread[0] > UNREAD_EVICT:
            return unread[1], f"{unread[0]} bytes of replies unread"
        idle = [c for c in self.connections
                if now - c.last_request >= (EVICT_IDLE if c.served else EVICT_GRACE)]
        if not idle:
            return None
        c = min(idle, key=lambda c: (c.served, c.last_request))
        what = "idle" if c.served else "no request completed"
        return c, f"{what} for {now - c.last_request:.1f} s"

    def _evict(self, newcomer: str) -> bool:
        """Table full: free a slot for `newcomer` (False: every connection is in use)."""
        found = self._evictee()
        if found is None:
            return False
        victim, why = found
        self.stats.evicted += 1
        self.warn.warning("evict", "clients reset to make room (client limit)",
                          "table full (%d clients): resetting %s (%s) for %s",
                          self.max_clients, victim.peer, why, newcomer)
        victim.release(reset=True)
        return True

    async def _adopt(self, conn: socket.socket) -> None:
        fd = conn.fileno()
        try:
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            _keepalive(conn)
            await self._loop.connect_accepted_socket(  # type: ignore[union-attr]
                lambda: _Connection(self), conn)
        except OSError:
            conn.close()
        finally:
            self._adopting.discard(fd)

    async def _sweep(self) -> None:
        """Close clients stuck mid-frame or silent for too long; summarise warnings."""
        limits = [t for t in (self.frame_timeout, self.idle_timeout) if t]
        period = min([*limits, 1.0]) / 4
        while True:
            await asyncio.sleep(period)
            now = time.monotonic()
            for c in list(self.connections):
                if c.partial_since is not None and self.frame_timeout \
                        and now - c.partial_since > self.frame_timeout:
                    c.drop("timeout", "clients closed for a timeout",
                           f"frame incomplete {self.frame_timeout:g} s after its first byte")
                elif self.idle_timeout and now - c.last_request > self.idle_timeout:
                    c.drop("timeout", "clients closed for a timeout",
                           f"no request for {self.idle_timeout:g} s")
            self.warn.flush()

    async def close(self) -> None:
        """Stop listening and close every client."""
        if self._sweeper is not None:
            self._sweeper.cancel()
        for s in self.sockets:
            if self._loop is not None:
                self._loop.remove_reader(s.fileno())
            s.close()
        for c in list(self.connections):
            if c.transport is not None:
                c.transport.close()
        for c in list(self.closing):
            if c.transport is not None:
                c.transport.abort()
        await asyncio.sleep(0)  # let connection_lost callbacks run
        self.warn.flush(force=True)


def _keepalive(conn: socket.socket) -> None:
    """TCP keepalive on an accepted socket (the timings where the platform has them)."""
    conn.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
    for name, value in KEEPALIVE:
        if hasattr(socket, name):
            conn.setsockopt(socket.IPPROTO_TCP, getattr(socket, name), value)


def _reset(conn: socket.socket) -> None:
    """Close with an RST: no FIN handshake, no TIME_WAIT, nothing read."""
    try:
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _LINGER_RESET)
    except OSError:
        pass
    conn.close()


def new_event_loop() -> asyncio.AbstractEventLoop:
    """uvloop's event loop when it is installed (its C event loop halves the server's CPU
    per request: docs/performance.md), else asyncio's. SOFTPLC_EVENT_LOOP=asyncio picks
    asyncio's anyway (for comparing the two, tools/bench_modbus_c.py)."""
    if os.environ.get("SOFTPLC_EVENT_LOOP", "") != "asyncio":
        try:
            import uvloop
        except ImportError:
            pass
        else:
            return uvloop.new_event_loop()
    return asyncio.new_event_loop()


class ServerThread:
    """Run a `ModbusTcpServer` on its own event loop in a background thread.

    The daemon keeps the main thread for the scan loop (precise sleeps, signals); tests
    and tools use this too.
    """

    def __init__(self, image: ModbusImage, host: str = "127.0.0.1", port: int = 5020,
                 **options: Any):
        self.server = ModbusTcpServer(image, host, port, **options)
        self.loop = new_event_loop()
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

    def set_priority(self, prio: int) -> None:
        """Put the server thread in SCHED_FIFO at `prio` (below the scan thread's). The
        scan thread waits for the GIL whenever this thread holds it: at normal priority a
        busy machine can preempt it while it holds the GIL, and the scan waits for the
        whole time slice (priority inversion: tens of ms under a connection storm)."""
        done = threading.Event()
        error: list[OSError] = []

        def apply() -> None:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
            except OSError as e:
                error.append(e)
            done.set()

        self.loop.call_soon_threadsafe(apply)
        done.wait(5)
        if error:
            raise error[0]

    def stop(self, timeout: float = 5.0) -> None:
        if self._thread.is_alive():
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(timeout)

    def __enter__(self) -> ServerThread:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
