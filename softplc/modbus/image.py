"""What hosts see of the memory image, and when; the one write path for every front-end.

Consistency rules (the scan never sees a half-applied request, clients never see a
half-finished scan):

- reads answer from a snapshot of %MW and %M taken at the end of the last scan
  (`take_snapshot`, run from the PLC's `after_scan` hooks), with the writes acknowledged
  since then laid over it: a real Twido serves requests between scans, so a host reads
  back what it has just written (the seed's host relies on it: it writes INICIO = 120 and
  waits for the PLC to clear it);
- writes wait in a pending image (one slot per register and per coil: the last value
  written wins) and all of them are applied together at the start of the next scan
  (`apply_writes`, run from `before_scan`), before inputs are latched. So an FC 16 frame
  lands in one piece, and however long the scan period, pending writes never take more
  memory than one copy of %MW and %M: nothing to refuse, no queue to grow.

With a retained-state store (`--state`), every write is journaled into it before the
caller acknowledges it, and every snapshot is committed to it: a process that dies loses
nothing it acknowledged (see `softplc.persist.retain`).

Front-ends call `write_words` / `write_bits`, which refuse with `WriteRefused` (carrying
the Modbus exception code that fits); the Modbus protocol code checks the same rules
itself on its hot path and calls `queue_registers` / `queue_coils`. The access port
(`softplc.access`, the web monitor's way in) uses the image as its word lane: typed
%MW/%MD/%MF/%M values (`queue_value`, encoded by the memory's own conversions) and the
configured read-only ranges by object (`read_only_object`), so a host reads back a
monitor's write exactly as its own.

The server and the scan may run in different threads: the snapshot is a bytearray of
fixed size, rewritten by single slice assignments (a memmove under the GIL: a reader's
slice sees all of it or none) and read only by slicing; a lock orders queueing a write
(and laying it over the snapshot) against applying the pending writes and taking a new
snapshot.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from struct import pack

import numpy as np

from softplc.errors import SoftPLCError
from softplc.modbus.regmap import COILS, REGISTERS, ExceptionCode, ReadOnly
from softplc.persist.retain import COILS as J_COILS
from softplc.persist.retain import REGISTERS as J_REGISTERS
from softplc.persist.retain import StateStore, be_to_words, words_to_be
from softplc.runtime.memory import MemoryImage, WordFamily
from softplc.twido.address import WIDTH
from softplc.twido.numeric import wrap16

#: a device's check of a value a host writes: (kind, index, value) -> why it is refused
ValueCheck = Callable[[str, int, float], "str | None"]

# Modbus registers are big-endian on the wire
words_to_wire = words_to_be
wire_to_words = be_to_words


class WriteRefused(SoftPLCError):
    """A host write that is not accepted; `code` is the Modbus exception that says why."""

    def __init__(self, message: str, code: ExceptionCode):
        super().__init__(message)
        self.code = code


class ModbusImage:
    """Snapshot for reads, pending image for writes, in front of a `MemoryImage`."""

    def __init__(self, mem: MemoryImage, read_only: ReadOnly | None = None, *,
                 store: StateStore | None = None,
                 blocks: Callable[[], bytes] | None = None, writes_allowed: bool = True):
        self.mem = mem
        self.read_only = read_only or ReadOnly()
        self.writes_allowed = writes_allowed  # False: `--read-only`, every write refused
        self.refused_why = ""  # why writes are refused when not `--read-only`
        self.value_checks: list[tuple[int, int, ValueCheck]] = []  # (check_values)
        self.n_registers = n = mem.mw.n
        self.n_coils = c = len(mem.m)
        self._regs_native = np.frombuffer(mem.mw.buf, np.uint16)
        # The pending image is bytearrays, written by slice assignment (one memmove per
        # request, no numpy call on the client's path), with numpy views for applying it.
        self._pend_regs_b = bytearray(2 * n)  # wire order, like the snapshot
        self._pend_rmask_b = bytearray(n)  # 1: register written since the last apply
        self._pend_coils_b = bytearray(c)
        self._pend_cmask_b = bytearray(c)
        self._pend_regs = np.frombuffer(self._pend_regs_b, ">u2")
        self._pend_rmask = np.frombuffer(self._pend_rmask_b, bool)
        self._pend_coils = np.frombuffer(self._pend_coils_b, np.uint8)
        self._pend_cmask = np.frombuffer(self._pend_cmask_b, bool)
        self._ones = b"\x01" * max(n, c)
        self._rlo, self._rhi, self._clo, self._chi = n, 0, c, 0  # pending bounds
        self._pending = 0  # writes acknowledged since the last apply
        self._lock = threading.Lock()
        self.written = threading.Event()  # set by every accepted write (see wait_for_write)
        self.store = store
        self._blocks = blocks
        self.hold = False  # True: keep the last snapshot (a scan was interrupted)
        # %MW as big-endian bytes, ready to slice into a response, and %M one byte (0/1)
        # per bit. Both keep their size: replaced by one slice assignment (a memmove, which
        # readers in another thread never see half done: the GIL is held throughout).
        self.regs_wire = bytearray(2 * n)
        self.coils = bytearray(c)
        # The boundary image the snapshot was last made from (%MW native, %M as the bit
        # list) and its wire form: a boundary whose memory equals it redoes no conversion.
        self._mw_seen = bytearray(mem.mw.buf)
        self._m_seen = list(mem.m)
        self._wire_seen = bytearray(words_to_wire(mem.mw.buf))
        self._wire_view = np.frombuffer(self._wire_seen, ">u2")
        self._coils_seen = bytes(mem.m)
        # True while `regs_wire`/`coils` hold host writes laid over the boundary image
        # (set by every accepted write; cleared by a snapshot taken with none pending)
        self._laid = True
        self.writes_applied = 0
        self.take_snapshot()

    def check_values(self, ranges: list[tuple[int, int]], refusal: ValueCheck) -> None:
        """Ask `refusal(kind, index, value)` about every %MF a host's register write
        covers whole inside `ranges` ([start, stop): %MF values from `start`, a device's
        `word_check`): a refused value is answered with exception 03 and not queued. A
        write of one register of such a float cannot be judged alone: it is queued (the
        device refuses the value it makes at its scan, as it always did)."""
        self.value_checks += [(lo, hi, refusal) for lo, hi in ranges]

    def refusal(self, addr: int, wire: bytes | bytearray) -> str | None:
        """Why a device refuses a write of big-endian register bytes at `addr`."""
        end = addr + len(wire) // 2
        for lo, hi, refusal in self.value_checks:
            first = max(lo, addr)
            first += (first - lo) % 2  # the first %MF starting inside the write
            for i in range(first, min(hi, end) - 1, 2):
                fam = WordFamily(WIDTH["MF"])
                fam.buf[:] = wire_to_words(wire[2 * (i - addr):2 * (i - addr) + 4])
                why = refusal("MF", i, fam.get_f(0))
                if why:
                    return why
        return None

    def protect(self, extra: ReadOnly) -> None:
        """Add read-only ranges (e.g. a device's status words) to those of the config."""
        ro = self.read_only
        self.read_only = ReadOnly(ro.registers + extra.registers, ro.coils + extra.coils)

    # -- scan side -----------------------------------------------------------------------
    def _overlay(self, regs: bytes | bytearray,
                 coils: bytes | bytearray) -> tuple[bytes | bytearray, bytes | bytearray]:
        """`regs`/`coils` with the pending writes laid over them (lock held)."""
        if self._rhi > self._rlo:
            r = np.frombuffer(regs, ">u2").copy()
            lo, hi = self._rlo, self._rhi
            np.copyto(r[lo:hi], self._pend_regs[lo:hi], where=self._pend_rmask[lo:hi])
            regs = r.tobytes()
        if self._chi > self._clo:
            cc = np.frombuffer(coils, np.uint8).copy()
            lo, hi = self._clo, self._chi
            np.copyto(cc[lo:hi], self._pend_coils[lo:hi], where=self._pend_cmask[lo:hi])
            coils = cc.tobytes()
        return regs, coils

    def snapshot_boundary(self) -> None:
        """`take_snapshot` whatever `hold`: for a caller in the scan thread between two
        scans (an online change's swap), whose memory is a boundary's even when the scan
        that follows is cut short."""
        self.take_snapshot(force=True)

    def take_snapshot(self, force: bool = False) -> None:
        """Copy %MW and %M for readers (and commit them to the store). After each scan
        (the daemon's `after_scan` hook), unless `hold` (`force`: whatever `hold`).

        Only what changed since the last boundary is converted (an idle or slow machine's
        boundary is two compares): the snapshot is rewritten when the memory differs
        from the image it was made from or host writes are laid over it; the store gets
        a commit at every boundary all the same (the blocks' state moves with time)."""
        if self.hold and not force:
            return
        mem = self.mem
        mw, m = mem.mw.buf, mem.m
        same_mw = mw == self._mw_seen  # a memcmp
        if not same_mw:
            self._mw_seen[:] = mw
            # native -> big-endian into a buffer of our own: numpy may let go of the GIL
            # while it copies, so readers only ever see the slice assignment below
            np.copyto(self._wire_view, self._regs_native)
        same_m = m == self._m_seen  # identity first: a pointer compare per bit
        if not same_m:
            self._m_seen[:] = m
            self._coils_seen = bytes(m)
        blocks = self._blocks() if self._blocks is not None else None
        with self._lock:
            if self._laid or not (same_mw and same_m):
                regs, coils = self._wire_seen, self._coils_seen
                if self._pending:  # acknowledged but not yet scanned: still what hosts read
                    regs, coils = self._overlay(regs, coils)
                self.regs_wire[:] = regs
                self.coils[:] = coils
                self._laid = bool(self._pending)  # laid over again at the next boundary
            if self.store is not None:
                self.store.commit(self.regs_wire, self.coils, blocks)

    def apply_writes(self) -> int:
        """Apply every pending write at once. Called at the start of a scan."""
        if not self._pending:
            return 0
        with self._lock:
            if self._rhi > self._rlo:
                lo, hi = self._rlo, self._rhi
                mask = self._pend_rmask[lo:hi]
                np.copyto(self._regs_native[lo:hi], self._pend_regs[lo:hi], where=mask)
                mask[:] = False
            if self._chi > self._clo:
                lo, hi = self._clo, self._chi
                m = self.mem.m
                for i in np.flatnonzero(self._pend_cmask[lo:hi]).tolist():
                    m[lo + i] = bool(self._pend_coils[lo + i])
                self._pend_cmask[lo:hi] = False
            n, self._pending = self._pending, 0
            self._rlo, self._rhi, self._clo, self._chi = self.n_registers, 0, self.n_coils, 0
        self.writes_applied += n
        return n

    @property
    def pending(self) -> int:
        """Writes acknowledged since the last scan start (coalesced in the pending image)."""
        return self._pending

    # -- client side ---------------------------------------------------------------------
    def read_registers_wire(self, addr: int, count: int) -> bytes:
        return self.regs_wire[2 * addr: 2 * (addr + count)]

    def read_coils_packed(self, addr: int, count: int) -> bytes:
        # a copy first: the scan thread rewrites `coils` in place (a slice is atomic)
        bits = np.frombuffer(self.coils[addr:addr + count], np.uint8)
        return np.packbits(bits, bitorder="little").tobytes()

    def queue_registers(self, addr: int, wire: bytes) -> None:
        """Accept a write of big-endian register bytes at register `addr` (checked)."""
        nb = len(wire)
        end = addr + nb // 2
        a2 = 2 * addr
        with self._lock:
            self._pend_regs_b[a2:a2 + nb] = wire
            self._pend_rmask_b[addr:end] = self._ones[:end - addr]
            if addr < self._rlo:
                self._rlo = addr
            if end > self._rhi:
                self._rhi = end
            self._pending += 1
            self.regs_wire[a2:a2 + nb] = wire  # read back at once (module docstring)
            self._laid = True
            store = self.store
            if store is not None and not store.journal(J_REGISTERS, addr, wire):
                store.commit(self.regs_wire, self.coils)  # includes this write
        self._signal()

    def queue_coils(self, addr: int, values: bytes) -> None:
        """Accept a write of coil values (one byte 0/1 per coil) at coil `addr` (checked)."""
        end = addr + len(values)
        with self._lock:
            self._pend_coils_b[addr:end] = values
            self._pend_cmask_b[addr:end] = self._ones[:end - addr]
            if addr < self._clo:
                self._clo = addr
            if end > self._chi:
                self._chi = end
            self._pending += 1
            self.coils[addr:end] = values
            self._laid = True
            store = self.store
            if store is not None and not store.journal(J_COILS, addr, values):
                store.commit(self.regs_wire, self.coils)
        self._signal()

    def _signal(self) -> None:
        # Event.set() takes a lock and notifies: skip it while the event is still set.
        # wait_for_write clears it before looking at `_pending` (incremented before
        # this), so a write that skips set() is seen there.
        if not self.written.is_set():
            self.written.set()

    def wait_for_write(self, timeout: float) -> bool:
        """Block until a write is pending (True) or `timeout` seconds pass (False); the
        scan side's way to sleep until a host has written something."""
        self.written.clear()
        if self._pending:  # a write that came before the clear
            return True
        return self.written.wait(timeout) or bool(self._pending)

    # -- any front-end -------------------------------------------------------------------
    def check_write(self, space: str, addr: int, count: int) -> None:
        """Raise WriteRefused if a write of `count` items at `addr` is not allowed."""
        if not self.writes_allowed:
            raise WriteRefused(self.refused_why or "writes are disabled (--read-only)",
                               ExceptionCode.ILLEGAL_FUNCTION)
        size = self.n_registers if space == REGISTERS else self.n_coils
        if addr < 0 or count < 1 or addr + count > size:
            raise WriteRefused(f"{space} {addr}..{addr + count - 1} outside 0..{size - 1}",
                               ExceptionCode.ILLEGAL_DATA_ADDRESS)
        if self.read_only.blocks(space, addr, count):
            raise WriteRefused(f"{space} {addr}..{addr + count - 1} are read-only",
                               ExceptionCode.ILLEGAL_DATA_ADDRESS)

    def write_words(self, addr: int, values: Iterable[int]) -> None:
        """Write %MW`addr`.. (16-bit values, signed or not) at the next scan start."""
        vals = [int(v) & 0xFFFF for v in values]
        self.check_write(REGISTERS, addr, len(vals))
        wire = pack(f">{len(vals)}H", *vals)
        why = self.refusal(addr, wire) if self.value_checks else None
        if why:
            raise WriteRefused(why, ExceptionCode.ILLEGAL_DATA_VALUE)
        self.queue_registers(addr, wire)

    def write_bits(self, addr: int, values: Iterable[int | bool]) -> None:
        """Write %M`addr`.. at the next scan start."""
        vals = bytes(1 if v else 0 for v in values)
        self.check_write(COILS, addr, len(vals))
        self.queue_coils(addr, vals)

    # -- the access port's word lane (typed objects) -----------------------------------
    def queue_value(self, kind: str, index: int, value: int | float) -> None:
        """Accept a checked value of %M`index` or %MW/%MD/%MF`index` (the access port
        checked it and its range)."""
        if kind == "M":
            self.queue_coils(index, b"\x01" if value else b"\x00")
            return
        fam = WordFamily(WIDTH[kind])  # encoded by the memory's own conversions
        if kind == "MW":
            fam.w[0] = wrap16(int(value))
        elif kind == "MD":
            fam.set_d(0, int(value))
        else:
            fam.set_f(0, float(value))
        self.queue_registers(index, words_to_wire(fam.buf))

    def read_only_object(self, kind: str, index: int, bit: int | None = None) -> bool:
        """Whether the configured read-only ranges cover %M`index` or the words of
        %MW/%MD/%MF`index` (a bit of a word: that word)."""
        if kind == "M":
            return self.read_only.blocks(COILS, index, 1)
        n = 1 if bit is not None else WIDTH[kind]
        return self.read_only.blocks(REGISTERS, index, n)
