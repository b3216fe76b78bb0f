"""A minimal blocking Modbus TCP client on a raw socket: for load generation (the
benchmark) and for tests that need to send exactly the bytes they want."""

from __future__ import annotations

import socket
from struct import pack, unpack

from softplc.modbus_codec import MBAP_SIZE, bad_header, frame, header


class ModbusExceptionReply(Exception):
    def __init__(self, fc: int, code: int):
        super().__init__(f"function {fc}: exception {code:02d}")
        self.fc, self.code = fc, code


class RawClient:
    def __init__(self, host: str = "127.0.0.1", port: int = 502, timeout: float = 2.0):
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.tid = 0

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> RawClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def recv_exact(self, n: int) -> bytes:
        buf = bytearray()
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("connection closed by the server")
            buf += chunk
        return bytes(buf)

    def recv_frame(self) -> tuple[int, int, bytes]:
        """One response: (transaction id, unit id, PDU)."""
        tid, pid, length, unit = header(self.recv_exact(MBAP_SIZE))
        why = bad_header(pid, length)
        if why is not None:
            raise ConnectionError(why)
        return tid, unit, self.recv_exact(length - 1)

    def request(self, pdu: bytes, unit: int = 1) -> bytes:
        """Send a PDU, return the response PDU (exception responses included)."""
        self.tid = (self.tid + 1) & 0xFFFF
        self.sock.sendall(frame(self.tid, unit, pdu))
        tid, u, resp = self.recv_frame()
        if tid != self.tid or u != unit:
            raise ConnectionError(f"reply for transaction {tid} unit {u}, expected "
                                  f"{self.tid} unit {unit}")
        return resp

    def call(self, pdu: bytes, unit: int = 1) -> bytes:
        """Like `request`, but raises ModbusExceptionReply for exception responses."""
        resp = self.request(pdu, unit)
        if resp[0] & 0x80:
            raise ModbusExceptionReply(resp[0] & 0x7F, resp[1])
        return resp

    def read_registers(self, addr: int, count: int, fc: int = 3) -> list[int]:
        resp = self.call(pack(">BHH", fc, addr, count))
        return list(unpack(f">{count}H", resp[2:]))

    def write_registers(self, addr: int, values: list[int]) -> None:
        n = len(values)
        self.call(pack(f">BHHB{n}H", 16, addr, n, 2 * n, *(v & 0xFFFF for v in values)))
