"""What Modbus clients see of the memory image, and when.

Consistency rules (the scan never sees a half-applied request, clients never see a
half-finished scan):

- reads answer from a snapshot of %MW and %M taken at the end of the last scan
  (`take_snapshot`, run from the PLC's `after_scan` hooks);
- writes are queued and applied at the start of the next scan (`apply_writes`, run from
  `before_scan`), before inputs are latched; one request is one queue entry, so an FC 16
  frame lands in one piece.

The server and the scan may run in different threads: the snapshot is an immutable
`bytes` object replaced by one reference assignment, and the queue is a `deque`, whose
append/popleft are atomic.
"""

from __future__ import annotations

import sys
from array import array
from collections import deque

import numpy as np

from ..runtime.memory import MemoryImage
from .regmap import ReadOnly

_SWAP = sys.byteorder == "little"  # Modbus registers are big-endian on the wire


def words_to_wire(buf: bytes | bytearray | memoryview) -> bytes:
    """Native unsigned 16-bit words -> big-endian bytes."""
    a = array("H", bytes(buf))
    if _SWAP:
        a.byteswap()
    return a.tobytes()


def wire_to_words(data: bytes) -> bytes:
    """Big-endian register bytes -> native 16-bit words."""
    a = array("H", data)
    if _SWAP:
        a.byteswap()
    return a.tobytes()


class ModbusImage:
    """Snapshot for reads, queue for writes, in front of a `MemoryImage`."""

    def __init__(self, mem: MemoryImage, read_only: ReadOnly | None = None):
        self.mem = mem
        self.read_only = read_only or ReadOnly()
        self.n_registers = mem.mw.n
        self.n_coils = len(mem.m)
        self._queue: deque[tuple[str, int, bytes]] = deque()
        self.regs_wire = b""  # %MW as big-endian bytes, ready to slice into a response
        self.coils = b""  # %M, one byte (0/1) per bit
        self.writes_applied = 0
        self.take_snapshot()

    # -- scan side -----------------------------------------------------------------------
    def take_snapshot(self) -> None:
        """Copy %MW and %M for readers. Called after each scan."""
        self.regs_wire = words_to_wire(self.mem.mw.buf)
        self.coils = bytes(self.mem.m)

    def apply_writes(self) -> int:
        """Apply every queued write, in arrival order. Called at the start of a scan."""
        q = self._queue
        n = 0
        while q:
            space, addr, data = q.popleft()
            if space == "r":
                self.mem.mw.buf[2 * addr: 2 * addr + len(data)] = data
            else:
                self.mem.m[addr: addr + len(data)] = data
            n += 1
        self.writes_applied += n
        return n

    @property
    def pending(self) -> int:
        return len(self._queue)

    # -- client side ---------------------------------------------------------------------
    def read_registers_wire(self, addr: int, count: int) -> bytes:
        return self.regs_wire[2 * addr: 2 * (addr + count)]

    def read_coils_packed(self, addr: int, count: int) -> bytes:
        bits = np.frombuffer(self.coils, np.uint8, count, addr)
        return np.packbits(bits, bitorder="little").tobytes()

    def queue_registers(self, addr: int, wire: bytes) -> None:
        """Queue a write of big-endian register bytes at register `addr`."""
        self._queue.append(("r", addr, wire_to_words(wire)))

    def queue_coils(self, addr: int, values: bytes) -> None:
        """Queue a write of coil values (one byte 0/1 per coil) at coil `addr`."""
        self._queue.append(("c", addr, values))
