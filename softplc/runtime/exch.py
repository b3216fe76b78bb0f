"""`EXCH3 %MWj:n` / `%MSG3`: the Twido as a Modbus TCP client on its Ethernet port.

The exchange table `%MWj:n` is laid out as the Twido's Modbus master table [manual, TWD USE
10AE "Modbus master", from memory: check on hardware]:

  word 0   high byte: command (1 = send then receive, 0 = send only); low byte: L, the
           transmission length in bytes
  word 1   high byte: reception offset; low byte: transmission offset (the 1-based rank of a
           padding byte that is not sent / is inserted in the reply so that words align;
           0 = none)
  word 2.. the transmission table, L bytes, high byte first: the first byte is the index of
           the remote device (TwidoSuite's Ethernet "remote devices" table, here
           `[exch.remote.<index>]`: host, port, unit id), then the Modbus PDU (function
           code, address, quantity, data...)
  then     the reception table, from word 2 + ceil(L / 2): the reply, index byte first,
           then the reply PDU, with a 0 byte inserted at the reception offset.

For "read N words" (FC03): `16#0106`, `16#0300`, `16#<idx>03`, address, N; the reply is
`16#<idx>03`, `16#00<2N>`, then the N words. The Twido does not interpret the function code:
any PDU goes (FC01/02/03/04/05/06/15/16 alike), which is why this is raw bytes over our own
MBAP framing rather than a Modbus library's typed calls.

Never blocking the scan: a worker thread does the socket work, on non-blocking sockets,
against one deadline per exchange (`timeout` after the request, for connecting, sending
and reading the whole reply: a remote dripping a byte every 0.4 s fails at the deadline
like a silent one; issue 21). The result is handed over at a scan boundary (the engine's
`before_scan` hook, `ExchPort.poll`). On the real clock the scan only looks whether the
reply arrived, and gives the exchange up (error 5) at the deadline whatever the worker is
doing. On the virtual clock (tests, `--speed max`) the outcome must land at the first scan
boundary after the request whatever the machine's load, so the virtual clock waits for it,
up to the deadline in wall time: the daemon waits in 0.1 s slices before the scan
(`build.settle_exchange`: signals stay prompt), `PLC.scan` at the boundary; a timeout is
delivered at the first scan whose virtual time is `timeout` after the request. Both make
the outcome a function of the peer's behaviour only, not of thread timing. The worker is a
daemon thread woken by a socket pair when the scan gives an exchange up, so neither
SIGTERM nor the process' exit ever waits for a remote.
"""

from __future__ import annotations

import errno
import math
import os
import select
import socket
import struct
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, InvalidStateError
from dataclasses import dataclass
from queue import SimpleQueue
from typing import Any

from softplc.modbus_codec import MBAP_SIZE, bad_header, frame, header
from softplc.runtime.blocks import Block

# Error codes of the EXCH status word [manual, %SW63/%SW64 list, from memory; check]
OK = 0
ERR_TX_TOO_LONG = 1  # more than MAX_TX_BYTES to send
ERR_TX_TABLE = 2  # the transmission table runs past the word table
ERR_TABLE = 3  # the word table is too small for the control words
ERR_RX_OVERFLOW = 4  # the reply does not fit in the reception table
ERR_TIMEOUT = 5  # no reply in time
ERR_TX = 6  # transmission error: cannot connect / send [our choice for TCP]
ERR_COMMAND = 7  # bad command in the table
ERR_DEVICE = 8  # remote device index not configured [our choice: "port not configured"]
ERR_RX = 9  # reception error: malformed reply
ERR_TX_OFFSET = 11  # transmission offset beyond the transmission table
ERR_RX_OFFSET = 12  # reception offset beyond the reception table
ERR_STOPPED = 13  # the controller stopped the exchange (STOP)

# The status word of each EXCH port [manual: %SW63 EXCH1, %SW64 EXCH2; %SW65 EXCH3 on the
# Ethernet base, from memory: check]
STATUS_WORD = {1: 63, 2: 64, 3: 65}
ETHERNET_PORT = 3  # EXCH3 / %MSG3: the TWDLCAE40DRF's Ethernet port [manual]
SERIAL_PORTS = (1, 2)
MAX_TX_BYTES = 250  # [manual, from memory]
CMD_SEND_ONLY, CMD_SEND_RECEIVE = 0, 1  # command byte [manual]; 2 (receive only) is serial


@dataclass(frozen=True)
class Remote:
    """One row of the Ethernet remote-devices table."""

    host: str
    port: int
    unit_id: int


@dataclass
class _Request:
    start: int  # first word of the table
    words: int  # n
    rx_start: int  # first word of the reception table
    rx_offset: int
    index: int  # remote device index (first transmitted byte)
    pdu: bytes
    expect_reply: bool


class ExchError(Exception):
    """An exchange failed with one of the EXCH error codes."""

    def __init__(self, code: int, detail: str = ""):
        super().__init__(detail or f"EXCH error {code}")
        self.code = code


def _table_bytes(words: Any, start: int, nbytes: int) -> bytes:
    out = bytearray()
    for k in range((nbytes + 1) // 2):
        out += struct.pack(">H", int(words[start + k]) & 0xFFFF)
    return bytes(out[:nbytes])


def build_request(mw: Any, start: int, n: int) -> _Request:
    """Decode the exchange table `%MW<start>:<n>`; raises ExchError on a malformed one."""
    if n < 3:
        raise ExchError(ERR_TABLE, f"table of {n} words: at least 3 (control words + data)")
    w0, w1 = int(mw[start]) & 0xFFFF, int(mw[start + 1]) & 0xFFFF
    command, length = w0 >> 8, w0 & 0xFF
    rx_offset, tx_offset = w1 >> 8, w1 & 0xFF
    if command not in (CMD_SEND_ONLY, CMD_SEND_RECEIVE):
        raise ExchError(ERR_COMMAND, f"command {command}: 0 (send) or 1 (send, receive)")
    if length > MAX_TX_BYTES:
        raise ExchError(ERR_TX_TOO_LONG, f"{length} bytes to send: at most {MAX_TX_BYTES}")
    tx_words = (length + 1) // 2
    if length < 2 or 2 + tx_words > n:
        raise ExchError(ERR_TX_TABLE, f"{length} bytes to send in a table of {n} words")
    if tx_offset > length:
        raise ExchError(ERR_TX_OFFSET, f"transmission offset {tx_offset} > length {length}")
    raw = bytearray(_table_bytes(mw, start + 2, length))
    if tx_offset:
        del raw[tx_offset - 1]  # the padding byte is not sent [manual]
    rx_start = 2 + tx_words
    if rx_offset > 2 * (n - rx_start):
        raise ExchError(ERR_RX_OFFSET, f"reception offset {rx_offset} beyond the table")
    if command == CMD_SEND_RECEIVE and rx_start >= n:
        raise ExchError(ERR_RX_OVERFLOW, "no room left for the reception table")
    return _Request(start, n, rx_start, rx_offset, raw[0], bytes(raw[1:]),
                    command == CMD_SEND_RECEIVE)


def store_reply(mw: Any, req: _Request, index: int, pdu: bytes) -> None:
    """Write the reply into the reception table (index byte, PDU, the padding byte at the
    reception offset); raises ExchError(ERR_RX_OVERFLOW) when it does not fit."""
    data = bytearray([index]) + pdu
    if req.rx_offset:
        data.insert(req.rx_offset - 1, 0)
    room = 2 * (req.words - req.rx_start)
    if len(data) > room:
        raise ExchError(ERR_RX_OVERFLOW, f"reply of {len(data)} bytes, room for {room}")
    if len(data) % 2:
        data.append(0)  # an odd last byte goes in the high byte [our choice]
    base = req.start + req.rx_start
    for k in range(len(data) // 2):
        v = data[2 * k] << 8 | data[2 * k + 1]
        mw[base + k] = v - 0x10000 if v & 0x8000 else v


class _Cancelled(Exception):
    """The scan gave up the exchange (deadline, %MSG reset, STOP, close)."""


class _Job:
    """One exchange handed to the worker: the request, its deadline (monotonic seconds)
    and its outcome, a Future set once (by the worker, or by the scan at the deadline)."""

    def __init__(self, conn: _Connection | None, pdu: bytes, expect_reply: bool,
                 deadline: float):
        self.conn, self.pdu, self.expect_reply, self.deadline = conn, pdu, expect_reply, deadline
        self.future: Future[bytes] = Future()
        self.cancelled = False

    def settle(self, result: bytes = b"", error: BaseException | None = None) -> None:
        """Set the outcome unless it is set already (the first one wins)."""
        try:
            if error is None:
                self.future.set_result(result)
            else:
                self.future.set_exception(error)
        except InvalidStateError:
            pass


class _Worker:
    """The port's I/O thread: runs the exchanges one after the other, every wait bounded
    by the exchange's deadline and woken at once by `cancel` (a socket pair). A daemon
    thread: a remote that hangs never delays the process' exit."""

    def __init__(self) -> None:
        self._queue: SimpleQueue[_Job | None] = SimpleQueue()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._current: _Job | None = None
        self._conns: list[_Connection] = []  # closed by the thread when it stops
        threading.Thread(target=self._run, name="exch", daemon=True).start()

    def submit(self, job: _Job) -> None:
        self._queue.put(job)

    def cancel(self, job: _Job) -> None:
        job.cancelled = True
        self._wake()

    def stop(self, conns: list[_Connection]) -> None:
        """End the thread once the exchange in progress is cancelled; it closes `conns`."""
        self._conns = conns
        if self._current is not None:
            self.cancel(self._current)
        self._queue.put(None)
        self._wake()

    def _wake(self) -> None:
        try:
            self._wake_w.send(b"x")
        except OSError:  # buffer full (a wake-up is pending anyway) or already closed
            pass

    def _drain(self) -> None:
        try:
            while self._wake_r.recv(256):
                pass
        except OSError:
            pass

    def wait(self, sock: socket.socket, write: bool, timeout: float) -> bool:
        """Wait up to `timeout` s for `sock` to be writable (`write`) or readable; False on
        timeout or a stale wake-up; raises _Cancelled if the exchange was given up."""
        p = select.poll()
        p.register(sock, select.POLLOUT if write else select.POLLIN)
        p.register(self._wake_r, select.POLLIN)
        events = p.poll(max(0, math.ceil(timeout * 1000)))
        if any(fd == self._wake_r.fileno() for fd, _ in events):
            self._drain()
        if self._current is not None and self._current.cancelled:
            raise _Cancelled
        return any(fd == sock.fileno() for fd, _ in events)

    def _run(self) -> None:
        while (job := self._queue.get()) is not None:
            assert job.conn is not None  # only socket exchanges reach the worker
            self._current = job
            self._drain()
            try:
                if job.cancelled:
                    raise _Cancelled
                job.settle(job.conn.exchange(job.pdu, job.expect_reply, job.deadline, self))
            except _Cancelled:
                job.conn.close()
                job.settle(error=ExchError(ERR_STOPPED, "exchange given up"))
            except ExchError as e:
                job.settle(error=e)
            except Exception as e:  # a bug must not leave the scan waiting for an outcome
                job.conn.close()
                job.settle(error=ExchError(ERR_RX, repr(e)))
            self._current = None
        for c in self._conns:
            c.close()
        self._wake_r.close()
        self._wake_w.close()


class _Connection:
    """One TCP connection to a remote device, reopened after an error. Used by the worker
    thread only: non-blocking socket, every wait through `_Worker.wait` until `deadline`."""

    def __init__(self, remote: Remote, timeout_s: float):
        self.remote, self.timeout_s = remote, timeout_s
        self.where = f"{remote.host}:{remote.port}"
        self.sock: socket.socket | None = None
        self.tid = 0

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def _wait(self, worker: _Worker, write: bool, deadline: float, what: str) -> None:
        assert self.sock is not None
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise ExchError(ERR_TIMEOUT, f"{self.where}: {what} in {self.timeout_s:g} s")
            if worker.wait(self.sock, write, left):
                return

    def _connect(self, deadline: float, worker: _Worker) -> None:
        # a host name is resolved here, blocking this thread only: the scan side gives
        # the exchange up at its deadline whatever this thread is doing
        infos = socket.getaddrinfo(self.remote.host, self.remote.port, type=socket.SOCK_STREAM)
        error: OSError = OSError(errno.EADDRNOTAVAIL, "no address")
        for family, kind, proto, _name, addr in infos:
            self.sock = s = socket.socket(family, kind, proto)
            s.setblocking(False)
            rc = s.connect_ex(addr)
            if rc in (errno.EINPROGRESS, errno.EWOULDBLOCK, errno.EAGAIN):
                self._wait(worker, True, deadline, "no connection")
                rc = s.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
            if rc == 0:
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                return
            error = OSError(rc, os.strerror(rc))
            self.close()
        raise error

    def _send(self, data: bytes, deadline: float, worker: _Worker) -> None:
        assert self.sock is not None
        view = memoryview(data)
        while view:
            try:
                view = view[self.sock.send(view):]
            except BlockingIOError:
                self._wait(worker, True, deadline, "no reply")

    def _recv(self, n: int, deadline: float, worker: _Worker) -> bytes:
        assert self.sock is not None
        buf = bytearray()
        while len(buf) < n:
            try:
                chunk = self.sock.recv(n - len(buf))
            except BlockingIOError:
                self._wait(worker, False, deadline, "no reply")
                continue
            if not chunk:
                raise ExchError(ERR_RX, "connection closed by the remote device")
            buf += chunk
        return bytes(buf)

    def exchange(self, pdu: bytes, expect_reply: bool, deadline: float,
                 worker: _Worker) -> bytes:
        """Send the request and read the reply, all before `deadline` (one deadline for
        the whole exchange: a remote dripping bytes cannot stretch it)."""
        try:
            try:
                if self.sock is None:
                    self._connect(deadline, worker)
                self.tid = (self.tid + 1) & 0xFFFF
                self._send(frame(self.tid, self.remote.unit_id, pdu), deadline, worker)
            except OSError as e:
                raise ExchError(ERR_TX, f"{self.where}: {e}") from None
            try:
                # the reply of a send-only request is read too, to keep the stream in step
                tid, proto, length, _unit = header(self._recv(MBAP_SIZE, deadline, worker))
                why = bad_header(proto, length)
                if why is not None or tid != self.tid:
                    raise ExchError(ERR_RX, f"{why or 'bad MBAP header'} (transaction {tid}, "
                                    f"expected {self.tid})")
                body = self._recv(length - 1, deadline, worker)
            except OSError as e:
                raise ExchError(ERR_RX, str(e)) from None
        except BaseException:
            self.close()
            raise
        return body if expect_reply else b""


class ExchPort:
    """The EXCH3 port: one exchange at a time, run by a worker thread; the scan only
    looks at its outcome (`poll`), or on the virtual clock waits for it (`settle`)."""

    def __init__(self, mem: Any, now_us: Callable[[], int], remotes: dict[int, Remote],
                 timeout_s: float, wait_at_boundary: bool, port: int = ETHERNET_PORT):
        self.mem, self.now_us = mem, now_us  # now_us: the PLC clock (virtual or real)
        self.remotes, self.timeout_s = remotes, timeout_s
        self.timeout_us = round(timeout_s * 1e6)
        self.wait = wait_at_boundary  # virtual clock: take the result at the next boundary
        self.status_word = STATUS_WORD[port]
        self.msg: Any = None  # the %MSG block (`Message`) this port drives
        self._worker: _Worker | None = None
        self._conns: dict[int, _Connection] = {}
        self._job: _Job | None = None
        self._req: _Request | None = None
        self._t0 = 0
        # remote devices served in this process (softplc.plant: another controller of the
        # plant): index -> its Modbus server's answer to a request PDU, given at once, no
        # socket (ExchError when it does not answer); the reply lands at the next scan
        # boundary like any other
        self.local: dict[int, Callable[[bytes], bytes]] = {}

    def start(self, start: int, n: int) -> None:
        """`EXCH3 %MW<start>:<n>` with the block done: check the table, send the request.
        Ignored while an exchange is in progress [manual: the program tests %MSG.D]."""
        msg = self.msg
        if self._job is not None:
            return
        try:
            req = build_request(self.mem.mw.w, start, n)
            remote = self.remotes.get(req.index)
            if remote is None:
                raise ExchError(ERR_DEVICE, f"remote device {req.index} not configured")
        except ExchError as e:
            self._finish(e.code)
            return
        msg.D, msg.E = 0, 0
        serve = self.local.get(req.index)
        if serve is not None:
            self._req, self._t0 = req, self.now_us()
            self._job = _Job(None, req.pdu, req.expect_reply, math.inf)
            try:  # a timeout shows once its time has passed on the clock (`poll`)
                self._job.settle(serve(req.pdu))
            except ExchError as e:
                self._job.settle(error=e)
            return
        if self._worker is None:
            self._worker = _Worker()
        conn = self._conns.get(req.index)
        if conn is None:
            conn = self._conns[req.index] = _Connection(remote, self.timeout_s)
        self._req, self._t0 = req, self.now_us()
        self._job = _Job(conn, req.pdu, req.expect_reply, time.monotonic() + self.timeout_s)
        self._worker.submit(self._job)

    def settle(self, timeout: float) -> bool:
        """Wait up to `timeout` s, never past the exchange's deadline, for the outcome of
        the exchange in progress; True once it is known (or there is none). At the
        deadline the exchange fails with ERR_TIMEOUT whatever the worker is doing."""
        job = self._job
        if job is None or job.future.done():
            return True
        left = job.deadline - time.monotonic()
        if left > 0:
            try:
                job.future.exception(timeout=min(timeout, left))
                return True
            except TimeoutError:
                if timeout < left:
                    return False
        self._expire(job)
        return True

    def _expire(self, job: _Job) -> None:
        job.settle(error=ExchError(ERR_TIMEOUT, f"no reply in {self.timeout_s:g} s"))
        assert self._worker is not None
        self._worker.cancel(job)

    def poll(self) -> None:
        """Scan boundary: hand a finished exchange's result to the table and the block."""
        job = self._job
        if job is None:
            return
        if self.wait:  # virtual clock: the outcome lands at this boundary; this waits only
            self.settle(math.inf)  # if the caller did not `settle` first (the daemon does)
        late = self.now_us() - self._t0 >= self.timeout_us
        if not job.future.done():
            if not late:
                return
            self._expire(job)  # real clock: the deadline has passed
        err = job.future.exception()
        if isinstance(err, ExchError) and err.code == ERR_TIMEOUT and not late:
            return  # on the virtual clock the timeout shows once its time has passed
        req = self._req
        assert req is not None
        self._job = self._req = None
        if err is not None:
            self._finish(err.code if isinstance(err, ExchError) else ERR_RX)
            return
        try:
            if req.expect_reply:
                store_reply(self.mem.mw.w, req, req.index, job.future.result())
        except ExchError as e:
            self._finish(e.code)
            return
        self._finish(OK)

    def _drop(self, code: int) -> None:
        """Abandon the exchange in progress (its connection is reopened next time)."""
        if self._job is not None and self._worker is not None:
            self._worker.cancel(self._job)
        self._job = self._req = None
        if code:
            self._finish(code)

    def _finish(self, code: int) -> None:
        self.mem.sw.w[self.status_word] = code
        self.msg.D, self.msg.E = 1, 1 if code else 0

    def reset(self) -> None:
        """%MSG R input: drop the exchange in progress; D = 1, E = 0 [manual]."""
        self._drop(OK)
        self.mem.sw.w[self.status_word] = 0

    def stop(self) -> None:
        """The controller left RUN: an exchange in progress ends with error 13 [manual]."""
        if self._job is not None:
            self._drop(ERR_STOPPED)

    def close(self) -> None:
        """Give up the exchange in progress and end the worker (it closes the
        connections); returns at once."""
        self._drop(OK)
        if self._worker is not None:
            self._worker.stop(list(self._conns.values()))
            self._worker = None
        self._conns.clear()


# ---- the %MSG block: the exchanges' state, as the program sees it ------------------------
class Message(Block):
    """%MSGi: the state of the exchanges of port i [manual]: D = 1 done (no exchange in
    progress), E = 1 the last exchange failed (code in the port's status word). R resets:
    the exchange in progress is dropped, D = 1, E = 0. `port` is the `ExchPort`
    the configuration gives (None: the port is not configured)."""

    PINS = ("R",)
    FIELDS = ("D", "E")

    def __init__(self) -> None:
        self.D, self.E = 1, 0
        self.port: Any = None

    def run(self, R: Any = 0) -> None:
        if R:
            if self.port is not None:
                self.port.reset()
            self.D, self.E = 1, 0

    def exch(self, start: int, n: int) -> None:
        """`EXCHi %MW<start>:<n>` (the compiler checked that the port is configured)."""
        self.port.start(start, n)
