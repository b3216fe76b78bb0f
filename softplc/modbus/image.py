"""What Modbus clients see of the memory image, and when.

Consistency rules (the scan never sees a half-applied request, clients never see a
half-finished scan):

- reads answer from a snapshot of %MW and %M taken at the end of the last scan
  (`take_snapshot`, run from the PLC's `after_scan` hooks), with the writes acknowledged
  since then laid over it: a real Twido serves requests between scans, so a host reads
  back what it has just written (the seed's host relies on it: it writes INICIO = 120 and
  waits for the PLC to clear it);
- writes are queued and applied at the start of the next scan (`apply_writes`, run from
  `before_scan`), before inputs are latched; one request is one queue entry, so an FC 16
  frame lands in one piece.

The server and the scan may run in different threads: snapshots are immutable `bytes`
replaced by one reference assignment; a lock orders queueing a write (and laying it over
the snapshot) against taking a new snapshot (which lays the still-queued writes over it).
"""

from __future__ import annotations

import sys
import threading
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
        # (space "r"/"c", address, native data, wire data for the snapshot overlay)
        self._queue: deque[tuple[str, int, bytes, bytes]] = deque()
        self._lock = threading.Lock()
        self.regs_wire = b""  # %MW as big-endian bytes, ready to slice into a response
        self.coils = b""  # %M, one byte (0/1) per bit
        self.writes_applied = 0
        self.take_snapshot()

    # -- scan side -----------------------------------------------------------------------
    def take_snapshot(self) -> None:
        """Copy %MW and %M for readers. Called after each scan."""
        regs = words_to_wire(self.mem.mw.buf)
        coils = bytes(self.mem.m)
        with self._lock:
            if self._queue:  # acknowledged but not yet scanned: still what hosts read
                r, c = bytearray(regs), bytearray(coils)
                for space, addr, _data, wire in self._queue:
                    if space == "r":
                        r[2 * addr: 2 * addr + len(wire)] = wire
                    else:
                        c[addr: addr + len(wire)] = wire
                regs, coils = bytes(r), bytes(c)
            self.regs_wire, self.coils = regs, coils

    def apply_writes(self) -> int:
        """Apply every queued write, in arrival order. Called at the start of a scan."""
        q = self._queue
        n = 0
        while q:
            space, addr, data, _wire = q.popleft()
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
        with self._lock:
            self._queue.append(("r", addr, wire_to_words(wire), wire))
            r = self.regs_wire
            self.regs_wire = r[:2 * addr] + wire + r[2 * addr + len(wire):]

    def queue_coils(self, addr: int, values: bytes) -> None:
        """Queue a write of coil values (one byte 0/1 per coil) at coil `addr`."""
        with self._lock:
            self._queue.append(("c", addr, values, values))
            c = self.coils
            self.coils = c[:addr] + values + c[addr + len(values):]
