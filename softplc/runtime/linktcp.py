"""The Remote Link between processes: the master's polls over TCP (issue 35).

A real Twido Remote Link is RS-485 at a fixed speed [remote-link.md A4, manual, from
memory]; between `softplc run` daemons it travels over TCP instead, one connection from the
master to each remote:

- a remote (`--link-listen HOST:PORT`) runs `RemoteService`: a listening socket whose
  threads answer each poll at once with the words of the remote's last scan, queue the
  master's words for its next scan boundary and tick the station once per link cycle of
  the master (the cycle travels in every poll), so that a silent master shows as absent;
- the master (`--link-remote ADDR=HOST:PORT` for each declared remote) runs
  `MasterService`: a thread that polls the remotes in address order once per link cycle
  (`TcpTransport`), each poll bounded by its slot (the cycle / the remotes), and queues
  the cycle's answers for the next scan boundary.

The exchange never runs inside a scan: the scan thread meets the link threads only in the
plc's `before_scan` hook (the queued cycles replayed, in order, through the same
`LinkMaster.cycle` / `LinkRemote.answer` / `tick` that the in-memory plant uses, so the
status words follow one set of rules) and its `after_scan` hook (the words to send next).
A remote that is killed closes its connection (or refuses it): the master's poll fails at
once and the remote is shown absent after `MISSES` link cycles; each cycle the master
tries to reconnect, so a restarted remote rejoins at its first answered poll without
restarting the master.

A frame (all big-endian): magic "TL", version, type (poll/answer), the remote's address,
the payload kind (words of a peer, bits of a remote I/O controller), the master's link
cycle in ms (0 in answers), an item count, then the items (16-bit signed words, or one
byte 0/1 per bit). A frame that is not one of these closes the connection.
"""

from __future__ import annotations

import logging
import os
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from softplc.errors import SoftPLCError
from softplc.runtime.remotelink import (
    PEER,
    REMOTE_IO,
    LinkMaster,
    LinkRemote,
    Reply,
    Request,
    default_cycle_us,
)
from softplc.twido.address import LINK_STATIONS, LINK_WORDS

log = logging.getLogger("softplc.link")

MAGIC, VERSION = b"TL", 1
POLL, ANSWER = 1, 2
WORDS, BITS = 1, 2
KIND_OF = {PEER: WORDS, REMOTE_IO: BITS}
ROLE_OF = {WORDS: PEER, BITS: REMOTE_IO}
HEADER = struct.Struct(">2sBBBBHB")  # magic, version, type, address, kind, cycle ms, count
MAX_BITS = 64  # a base's inputs or outputs, with room (a Twido base has at most 24 inputs)
MAX_CYCLE_MS = 0xFFFF  # the field's range; a real link cycle is tens of ms
# Queued link cycles (master) or events (remote) waiting for a scan boundary: when scans
# stop coming (a long period), the oldest are dropped; the status words stay right, as
# they count misses, not the cycles that were seen.
MAX_PENDING = 256
CONNECT_SLOT_S = 0.5  # the longest a connect or a poll may take, whatever the slot
IDLE_S = 60.0  # a master connection that sends no poll for this long is closed
BACKLOG = 8


class LinkFrameError(ValueError):
    """A frame that is not a Remote Link frame (the connection is closed)."""


def endpoint(text: str) -> tuple[str, int]:
    """"HOST:PORT" (HOST an IPv4 address or name, PORT 0..65535); ValueError if not."""
    host, sep, port = text.strip().rpartition(":")
    if not sep or not host or not port.isdigit() or len(port) > 5 or int(port) > 0xFFFF:
        raise ValueError(f"{text!r}: write HOST:PORT, e.g. 127.0.0.1:5101")
    return host, int(port)


def _items(kind: int, words: tuple[int, ...] | None,
           bits: tuple[bool, ...] | None) -> tuple[int, bytes]:
    if kind == WORDS:
        w = tuple(words or ())[:LINK_WORDS]
        return len(w), struct.pack(f">{len(w)}h", *(((v + 0x8000) & 0xFFFF) - 0x8000
                                                       for v in w))
    b = tuple(bits or ())[:MAX_BITS]
    return len(b), bytes(1 if v else 0 for v in b)


def encode_poll(address: int, role: str, cycle_us: int, request: Request) -> bytes:
    kind = KIND_OF[role]
    n, body = _items(kind, request.words, request.outputs)
    cycle_ms = min(MAX_CYCLE_MS, max(1, cycle_us // 1000))
    return HEADER.pack(MAGIC, VERSION, POLL, address, kind, cycle_ms, n) + body


def encode_answer(address: int, reply: Reply) -> bytes:
    kind = KIND_OF[reply.role]
    n, body = _items(kind, reply.words, reply.inputs)
    return HEADER.pack(MAGIC, VERSION, ANSWER, address, kind, 0, n) + body


def _recv(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("connection closed")
        data += chunk
    return data


def read_frame(sock: socket.socket, expect: int) -> tuple[int, int, int, tuple[int, ...]]:
    """One frame of type `expect`: (address, kind, cycle ms, items)."""
    magic, version, ftype, address, kind, cycle_ms, n = HEADER.unpack(
        _recv(sock, HEADER.size))
    if magic != MAGIC or version != VERSION or ftype != expect:
        raise LinkFrameError(f"not a Remote Link frame (magic {magic!r}, version {version}, "
                             f"type {ftype})")
    if not 1 <= address < LINK_STATIONS or kind not in ROLE_OF:
        raise LinkFrameError(f"address {address} or payload kind {kind} out of range")
    if expect == POLL and not cycle_ms:
        raise LinkFrameError("a poll names the master's link cycle, at least 1 ms")
    if n > (LINK_WORDS if kind == WORDS else MAX_BITS):
        raise LinkFrameError(f"{n} items: too many for one poll")
    if kind == WORDS:
        items = struct.unpack(f">{n}h", _recv(sock, 2 * n))
    else:
        raw = _recv(sock, n)
        if any(b > 1 for b in raw):
            raise LinkFrameError("a bit is 0 or 1")
        items = tuple(raw)
    return address, kind, cycle_ms, items


def _listen(host: str, port: int) -> socket.socket:
    try:
        info = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
        sock = socket.socket(info[0], socket.SOCK_STREAM)
        # a restarted remote binds its port again at once, despite the old connections
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(info[4])
        sock.listen(BACKLOG)
    except OSError as e:
        raise SoftPLCError(f"--link-listen {host}:{port}: cannot listen: "
                           f"{e.strerror or e}") from None
    return sock


class TcpTransport:
    """The master's side: one connection per remote, opened (again) when needed. `poll`
    waits at most `slot_s` for the answer; a refused, reset or silent remote is None."""

    def __init__(self, endpoints: dict[int, tuple[str, int]], roles: dict[int, str],
                 cycle_us: int, slot_s: float):
        self.endpoints = endpoints
        self.roles = roles
        self.cycle_us = cycle_us
        self.slot_s = slot_s
        self.socks: dict[int, socket.socket] = {}

    def poll(self, address: int, request: Request) -> Reply | None:
        try:
            sock = self.socks.get(address)
            if sock is None:
                sock = socket.create_connection(self.endpoints[address], timeout=self.slot_s)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.socks[address] = sock
            sock.settimeout(self.slot_s)
            sock.sendall(encode_poll(address, self.roles[address], self.cycle_us, request))
            got, kind, _, items = read_frame(sock, ANSWER)
        except (OSError, ConnectionError, LinkFrameError, struct.error) as e:
            self.drop(address)
            log.debug("remote %d: no answer (%s)", address, e)
            return None
        if got != address:  # another station answers at this endpoint: not ours
            self.drop(address)
            return None
        role = ROLE_OF[kind]
        if role == PEER:
            return Reply(role, words=items)
        return Reply(role, inputs=tuple(bool(b) for b in items))

    def drop(self, address: int) -> None:
        sock = self.socks.pop(address, None)
        if sock is not None:
            sock.close()

    def close(self) -> None:
        for a in list(self.socks):
            self.drop(a)


class _Recorded:
    """A transport that gives back the answers of one link cycle already run."""

    def __init__(self, replies: dict[int, Reply | None]):
        self.replies = replies

    def poll(self, address: int, request: Request) -> Reply | None:
        return self.replies.get(address)


class _Service:
    """What both ends share: a thread, a lock, the scan hooks."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.stopping = threading.Event()
        self.threads: list[threading.Thread] = []
        # SCHED_FIFO priority of the link's threads (0: normal). The daemon gives them its
        # Modbus thread's: at normal priority a busy machine delays an answer past its slot
        # and a present remote would show absent.
        self.priority = 0

    def attach(self, plc: Any) -> None:
        """Meet the scan only at its boundaries (plc.before_scan / after_scan)."""
        plc.before_scan.append(self.before_scan)
        plc.after_scan.append(self.after_scan)
        self.after_scan()

    def _spawn(self, target: Callable[..., None], name: str, *args: Any) -> None:
        def run() -> None:
            if self.priority:
                try:
                    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.priority))
                except (AttributeError, OSError) as e:  # not permitted: normal priority
                    log.debug("link thread at normal priority: %s", e)
            target(*args)
        t = threading.Thread(target=run, name=name, daemon=True)
        self.threads = [*(x for x in self.threads if x.is_alive()), t]  # ended connections go
        t.start()

    def before_scan(self) -> None:
        raise NotImplementedError

    def after_scan(self) -> None:
        raise NotImplementedError

    def stop(self) -> None:
        self.stopping.set()
        self._close()
        for t in self.threads:
            t.join(timeout=2 * CONNECT_SLOT_S + 1)

    def _close(self) -> None:
        raise NotImplementedError


class _Listening(_Service):
    """A service answering on a listening socket `sock`, one connection `conn` at a time
    (a remote's link, a daemon's wires)."""

    sock: socket.socket
    conn: socket.socket | None

    def _close(self) -> None:
        try:  # wakes the thread blocked in accept() (close alone does not, on Linux)
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()
        with self.lock:
            conn, self.conn = self.conn, None
        if conn is not None:
            _hang_up(conn)


class MasterService(_Service):
    """The master's link thread: one `run_cycle()` per link cycle."""

    def __init__(self, master: LinkMaster, endpoints: dict[int, tuple[str, int]]):
        super().__init__()
        missing = sorted(set(master.remotes) - set(endpoints))
        extra = sorted(set(endpoints) - set(master.remotes))
        if missing or extra:
            raise SoftPLCError(
                "--link-remote: " + "; ".join(
                    [f"remote {a} is declared in [remote_link] but has no ADDR=HOST:PORT"
                     for a in missing]
                    + [f"remote {a} is not declared in [remote_link] remotes" for a in extra]))
        self.master = master
        slot = master.cycle_us / 1e6 / len(master.remotes)
        self.transport = TcpTransport(endpoints, master.remotes, master.cycle_us,
                                      min(CONNECT_SLOT_S, slot))
        self.requests: dict[int, Request] = {}
        self.pending: deque[dict[int, Reply | None]] = deque(maxlen=MAX_PENDING)
        self.cycles = 0

    def banner(self) -> str:
        to = ", ".join(f"{a}={h}:{p}" for a, (h, p) in self.transport.endpoints.items())
        return (f"Remote Link: master, every {self.master.cycle_us / 1000:g} ms polls "
                f"{to} (TCP)")

    def after_scan(self) -> None:
        m = self.master
        with self.lock:
            self.requests = {a: m.request(a, role) for a, role in m.remotes.items()}

    def before_scan(self) -> None:
        with self.lock:
            cycles = list(self.pending)
            self.pending.clear()
        for replies in cycles:
            self.master.transport = _Recorded(replies)
            self.master.cycle()

    def run_cycle(self) -> None:
        """Poll every declared remote once, in address order; queue the answers."""
        with self.lock:
            requests = dict(self.requests)
        replies = {a: self.transport.poll(a, requests.get(a, Request()))
                   for a in self.master.remotes}
        with self.lock:
            self.pending.append(replies)
            self.cycles += 1

    def start(self) -> None:
        self._spawn(self._loop, "remote-link-master")

    def _loop(self) -> None:
        period = self.master.cycle_us / 1e6
        due = time.monotonic()
        while not self.stopping.is_set():
            self.run_cycle()
            due += period
            now = time.monotonic()
            if due < now:  # a cycle overran (a silent remote): the next starts now
                due = now
            self.stopping.wait(due - now)

    def _close(self) -> None:
        pass  # the loop closes its connections as it ends

    def stop(self) -> None:
        super().stop()
        self.transport.close()


class RemoteService(_Listening):
    """A remote's listening socket: answers each poll from its last scan, queues what the
    master sent, ticks once per master cycle."""

    def __init__(self, remote: LinkRemote, host: str, port: int):
        super().__init__()
        self.remote = remote
        self.sock = _listen(host, port)
        self.address = self.sock.getsockname()[:2]
        self.reply = remote.reply()
        self.events: deque[Request | None] = deque(maxlen=MAX_PENDING)  # None: a tick
        # the master's cycle, learnt from its polls; until then the longest default one
        self.cycle_us = default_cycle_us(LINK_STATIONS - 1)
        self.conn: socket.socket | None = None
        self.polls = 0

    def banner(self) -> str:
        host, port = self.address
        return (f"Remote Link: {self.remote.role} at address {self.remote.address}, "
                f"answering polls on {host}:{port} (TCP)")

    def after_scan(self) -> None:
        reply = self.remote.reply()
        with self.lock:
            self.reply = reply

    def before_scan(self) -> None:
        with self.lock:
            events = list(self.events)
            self.events.clear()
        for ev in events:
            if ev is None:
                self.remote.tick()
            else:
                self.remote.answer(ev)

    def start(self) -> None:
        self._spawn(self._accept, "remote-link-listen")
        self._spawn(self._ticks, "remote-link-tick")

    def _ticks(self) -> None:
        due = time.monotonic()
        while not self.stopping.is_set():
            due += self.cycle_us / 1e6
            now = time.monotonic()
            if due < now:
                due = now
            if self.stopping.wait(due - now):
                break
            with self.lock:
                self.events.append(None)

    def _accept(self) -> None:
        while not self.stopping.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return  # closed: stopping
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(IDLE_S)
            with self.lock:  # one master: a new connection (it restarted) replaces the old
                old, self.conn = self.conn, conn
            if old is not None:
                _hang_up(old)  # its thread wakes, sees the end and closes it
            self._spawn(self._serve, "remote-link-conn", conn)

    def _serve(self, conn: socket.socket) -> None:
        me, role = self.remote.address, self.remote.role
        try:
            while not self.stopping.is_set():
                address, kind, cycle_ms, items = read_frame(conn, POLL)
                if address != me or ROLE_OF[kind] != role:
                    log.warning("Remote Link: a poll for address %d (%s) at address %d "
                                "(%s): closed", address, ROLE_OF[kind], me, role)
                    return
                request = Request(words=items) if kind == WORDS else \
                    Request(outputs=tuple(bool(b) for b in items))
                with self.lock:
                    self.events.append(request)
                    self.cycle_us = cycle_ms * 1000
                    reply = self.reply
                    self.polls += 1
                conn.sendall(encode_answer(me, reply))
        except (OSError, ConnectionError, LinkFrameError, struct.error) as e:
            log.debug("Remote Link connection ended: %s", e)
        finally:
            conn.close()



def _hang_up(conn: socket.socket) -> None:
    """End a connection another thread may be reading: shutdown wakes its recv (a close
    alone does not, and its descriptor could be reused under it); that thread closes it."""
    try:
        conn.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
