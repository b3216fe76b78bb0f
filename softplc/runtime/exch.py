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

Never blocking the scan: a worker thread does the socket work. The result is handed over at
a scan boundary (the engine's `before_scan` hook, `ExchPort.poll`). On the real clock the
scan only looks whether the reply arrived; the timeout is the real time since the request.
On the virtual clock (tests, `--speed max`) the first scan boundary after the request waits
for the worker, so the reply lands at the next scan whatever the machine's load; a timeout
(no reply within `timeout` wall seconds) is delivered at the first scan whose virtual time
is `timeout` after the request. Both make the outcome a function of the peer's behaviour
only, not of thread timing.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

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
MBAP = struct.Struct(">HHHB")  # transaction id, protocol 0, length, unit id


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


class _Connection:
    """One TCP connection to a remote device, reopened after an error."""

    def __init__(self, remote: Remote, timeout_s: float):
        self.remote, self.timeout_s = remote, timeout_s
        self.sock: socket.socket | None = None
        self.tid = 0

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def _recv(self, n: int) -> bytes:
        assert self.sock is not None
        buf = b""
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ExchError(ERR_RX, "connection closed by the remote device")
            buf += chunk
        return buf

    def exchange(self, pdu: bytes, expect_reply: bool) -> bytes:
        try:
            if self.sock is None:
                self.sock = socket.create_connection((self.remote.host, self.remote.port),
                                                     timeout=self.timeout_s)
            self.tid = (self.tid + 1) & 0xFFFF
            self.sock.sendall(MBAP.pack(self.tid, 0, len(pdu) + 1, self.remote.unit_id) + pdu)
        except TimeoutError:
            self.close()
            raise ExchError(ERR_TIMEOUT, f"{self.remote.host}:{self.remote.port}: "
                            f"no connection in {self.timeout_s} s") from None
        except OSError as e:
            self.close()
            raise ExchError(ERR_TX, f"{self.remote.host}:{self.remote.port}: {e}") from None
        try:
            # the reply of a send-only request is read too, to keep the stream in step
            tid, proto, length, _unit = MBAP.unpack(self._recv(MBAP.size))
            if proto != 0 or length < 2 or tid != self.tid:
                raise ExchError(ERR_RX, f"bad MBAP header (transaction {tid}, protocol "
                                f"{proto}, length {length})")
            return self._recv(length - 1) if expect_reply else b""
        except TimeoutError:
            self.close()
            raise ExchError(ERR_TIMEOUT, f"no reply in {self.timeout_s} s") from None
        except ExchError:
            self.close()
            raise
        except OSError as e:
            self.close()
            raise ExchError(ERR_RX, str(e)) from None


class ExchPort:
    """The EXCH3 port: one exchange at a time, run by a worker thread."""

    def __init__(self, mem: Any, now_us: Callable[[], int], remotes: dict[int, Remote],
                 timeout_s: float, wait_at_boundary: bool, port: int = ETHERNET_PORT):
        self.mem, self.now_us = mem, now_us  # now_us: the PLC clock (virtual or real)
        self.remotes, self.timeout_s = remotes, timeout_s
        self.timeout_us = round(timeout_s * 1e6)
        self.wait = wait_at_boundary  # virtual clock: take the result at the next boundary
        self.status_word = STATUS_WORD[port]
        self.msg: Any = None  # the %MSG block (runtime.blocks.Message) this port drives
        self._pool: ThreadPoolExecutor | None = None
        self._conns: dict[int, _Connection] = {}
        self._job: Future[bytes] | None = None
        self._req: _Request | None = None
        self._t0 = 0

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
        if self._pool is None:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="exch")
        conn = self._conns.get(req.index)
        if conn is None:
            conn = self._conns[req.index] = _Connection(remote, self.timeout_s)
        self._req, self._t0 = req, self.now_us()
        self._job = self._pool.submit(conn.exchange, req.pdu, req.expect_reply)

    def poll(self) -> None:
        """Scan boundary: hand a finished exchange's result to the table and the block."""
        job = self._job
        if job is None:
            return
        late = self.now_us() - self._t0 >= self.timeout_us
        if not job.done():
            if not self.wait:
                if late:  # real clock: the worker's own timeout ends the socket later
                    self._drop(ERR_TIMEOUT)
                return
            try:  # virtual clock: the worker ends by its socket timeout at the latest
                job.exception(timeout=self.timeout_s * 4 + 1.0)
            except TimeoutError:
                self._drop(ERR_TIMEOUT)
                return
        err = job.exception()
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
                store_reply(self.mem.mw.w, req, req.index, job.result())
        except ExchError as e:
            self._finish(e.code)
            return
        self._finish(OK)

    def _drop(self, code: int) -> None:
        """Abandon the exchange in progress (its connection is reopened next time)."""
        if self._req is not None:
            conn = self._conns.pop(self._req.index, None)
            if conn is not None and self._job is not None:
                self._job.add_done_callback(lambda _f: conn.close())
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
        self._drop(OK)
        for c in self._conns.values():
            c.close()
        self._conns.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
