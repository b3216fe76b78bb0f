"""Hardwired signals between hosts: the plant host drives a controller's wired inputs and
reads its wired outputs over TCP (issue 35, `plant up`; docs/decisions/wires-over-tcp.md).

A wire of a plant file (`[[wires]]`) is a 24 V cable in a real line. When the controllers
run as hosts of their own, the shared physical process (the plant's devices and wires,
`softplc plant process`) runs as a host of its own too, and talks to each controller with
a wired input or output through one TCP connection (`softplc run --wire-listen`):

- the plant host sends a SET frame every device tick: the values of the controller's
  wired inputs, in the order of its `--wire-in` list;
- the controller answers at once with an OUTPUTS frame: its wired outputs of the last
  scan, in the order of its `--wire-out` list.

A frame (big-endian): magic "TW", version, type (SET/OUTPUTS), the layout (CRC-32 of the
wired inputs' and outputs' names, so the two ends agree on what each bit is), a bit
count, then one byte 0/1 per bit. Anything else closes the connection. The controller's
side is `softplc.access.wires.WireService`; the plant host's is `WireClient` here.
"""

from __future__ import annotations

import logging
import socket
import struct
import time
import zlib
from collections.abc import Sequence

from softplc.runtime.linktcp import MAX_BITS, _recv

log = logging.getLogger("softplc.wire")

MAGIC, VERSION = b"TW", 1
SET, OUTPUTS = 1, 2
HEADER = struct.Struct(">2sBBIB")  # magic, version, type, layout, count
MAX_WIRED = MAX_BITS  # wired inputs (or outputs) of one controller: a base's, with room
# How long a wired input keeps its last value without a frame from the plant host before
# it reads 0, as a cut cable reads 0 on a 24 V sink input [manual, from memory: a Twido DC
# input is off below 5 V]. Ten device ticks of 10 ms, and more than a loaded host's hiccup.
HOLD_S = 0.5
RETRY_S = 0.5  # the plant host tries a controller that does not answer this often
EXCHANGE_S = 0.2  # the longest a connect or an exchange with one controller may take


class WireFrameError(ValueError):
    """A frame that is not a wire frame (the connection is closed)."""


def layout(inputs: Sequence[str], outputs: Sequence[str]) -> int:
    """The CRC-32 both ends compute from the wired inputs' and outputs' names."""
    return zlib.crc32(("in:" + ",".join(inputs) + ";out:" + ",".join(outputs)).encode())


def encode(ftype: int, lay: int, bits: Sequence[bool]) -> bytes:
    if len(bits) > MAX_WIRED:
        raise ValueError(f"{len(bits)} wired signals: at most {MAX_WIRED}")
    return HEADER.pack(MAGIC, VERSION, ftype, lay, len(bits)) + bytes(1 if b else 0
                                                                     for b in bits)


def read_frame(sock: socket.socket, expect: int, lay: int, count: int) -> tuple[bool, ...]:
    """One frame of type `expect` with layout `lay` and `count` bits: the bits."""
    magic, version, ftype, got, n = HEADER.unpack(_recv(sock, HEADER.size))
    if magic != MAGIC or version != VERSION or ftype != expect:
        raise WireFrameError(f"not a wire frame (magic {magic!r}, version {version}, "
                             f"type {ftype})")
    if got != lay or n != count:
        raise WireFrameError(f"layout {got:08x} with {n} bits, expected {lay:08x} with "
                             f"{count}: the two ends were started from different wires")
    raw = _recv(sock, n)
    if any(b > 1 for b in raw):
        raise WireFrameError("a bit is 0 or 1")
    return tuple(bool(b) for b in raw)


class WireClient:
    """The plant host's end of one controller's wires: `exchange` sends the wired inputs
    and returns the wired outputs, None while the controller does not answer (then its
    outputs read 0: a controller without power drives nothing)."""

    def __init__(self, name: str, where: tuple[str, int], inputs: Sequence[str],
                 outputs: Sequence[str], timeout_s: float = EXCHANGE_S):
        self.name, self.where = name, where
        self.n_in, self.n_out = len(inputs), len(outputs)
        self.layout = layout(inputs, outputs)
        self.timeout_s = timeout_s
        self.sock: socket.socket | None = None
        self.next_try = 0.0
        self.exchanges = 0
        self.failures = 0

    @property
    def connected(self) -> bool:
        return self.sock is not None

    def exchange(self, inputs: Sequence[bool]) -> tuple[bool, ...] | None:
        now = time.monotonic()
        if self.sock is None:
            if now < self.next_try:
                return None
            self.next_try = now + RETRY_S
            try:
                self.sock = socket.create_connection(self.where, timeout=self.timeout_s)
                self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except OSError as e:
                log.debug("%s: no connection (%s)", self.name, e)
                self.sock = None
                return None
        try:
            self.sock.settimeout(self.timeout_s)
            self.sock.sendall(encode(SET, self.layout, inputs))
            out = read_frame(self.sock, OUTPUTS, self.layout, self.n_out)
        except (OSError, ConnectionError, WireFrameError, struct.error) as e:
            log.warning("%s: wires lost (%s)", self.name, e)
            self.failures += 1
            self.close()
            return None
        self.exchanges += 1
        return out

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None
