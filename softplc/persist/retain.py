"""Retained state: %MW, %M and function-block values kept across restarts (`--state FILE`).

A Twido keeps its data in battery-backed RAM: nothing it acknowledged is lost when it is
cut off. Here the retained image lives in a memory-mapped file (`StateStore`): a write
into a shared mapping is in the kernel's page cache as soon as it is made, and the kernel
keeps it when the process dies (kill -9, a crash, the OOM killer). So the image of every
scan boundary, and every host write before it is acknowledged, is stored without a system
call; `msync` every save interval makes it durable against power loss as well.

File format (version 2): little-endian, every region page-aligned::

    page 0    header: b"SOFTPLC-STATE 2\\n", layout (register and coil counts, blocks and
              journal capacities), profile name, crc32 of all that; at byte 256 the pid
              of the daemon holding the lock (informative, outside the checksum)
    slot 0, 1 volatile images, rewritten alternately at every scan boundary
    slot 2, 3 durable copies, rewritten alternately every save interval, then msync'ed
    journal   writes acknowledged since the newest volatile slot, appended in order

    slot    = seq (u64), application hash (32 bytes), blocks length (u32), crc32 (u32),
              then %MW as big-endian words, %M one byte per bit, blocks as JSON
    journal entry = generation (u64: the seq of the slot it follows), space (0 = %MW,
              1 = %M), address (u16), data length (u16), crc32 (u32), data

A slot's header is written after its payload and checks it, so a slot being written when
the process dies does not verify and the other one is used. Loading takes the verified
slot with the highest seq and replays the journal entries of its generation up to the
first that does not verify (a write cut off before it was acknowledged).

Starting with a state file that does not exist (or is empty: a creation that never
finished) is a cold start. A file that is present but unreadable, truncated, corrupt or
for another controller is an error unless the user asks for a cold start: the data is
never reset silently. The file is locked (`flock`) while a daemon uses it. A symbolic link
is refused unless the caller asks (`follow_symlinks`): `--cold` would overwrite whatever it
points to. While the store is open, `check` tells whether the file at the path is still
the locked one (deleted, renamed or replaced by another: it is not) and `recreate` writes
the whole mapped file, every acknowledged write included, to the path again, locked
(`softplc.persist.keeper` does both, ten times a second).

The format is fed by plain bytes (`StateStore.commit`) and `capture`/`apply` turn a
`MemoryImage` into a `RetainedState` and back, so another way of collecting the state
(e.g. an engine snapshot API) can feed the same store.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import logging
import mmap
import os
import struct
import sys
import threading
import zlib
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softplc.errors import SoftPLCError
from softplc.limits import BoundsError, check_digits
from softplc.runtime.memory import MemoryImage

log = logging.getLogger("softplc.retain")

MAGIC = b"SOFTPLC-STATE 2\n"
FORMAT_VERSION = 2
PAGE = mmap.PAGESIZE
_HINT = "; start with --cold to discard it and cold-start"
_HEADER = struct.Struct("<16sIIIII32sI")  # magic version n_regs n_coils blocks journal prof crc
_PID = struct.Struct("<I")
_PID_OFFSET = 256
_SLOT = struct.Struct("<Q32sII")  # seq, application hash, blocks length, crc32
_ENTRY = struct.Struct("<QBHHI")  # generation, space, address, data length, crc32
REGISTERS, COILS = 0, 1  # journal entry spaces
VOLATILE, DURABLE = (0, 1), (2, 3)
BLOCKS_MIN_CAPACITY = 64 * 1024  # bytes of blocks JSON a slot holds (at least)
JOURNAL_CAPACITY = 64 * 1024  # bytes; when full, the store commits a new slot instead
_SWAP = sys.byteorder == "little"


class StateFileError(SoftPLCError):
    """A retained-state file cannot be used."""


#: Bounds of a state file's header (checked before anything is mapped or copied): the
#: Modbus address space holds 65,536 registers and 65,536 coils, which no Twido exceeds;
#: a slot's blocks JSON and the journal are 64 KiB by default (BLOCKS_MIN_CAPACITY,
#: JOURNAL_CAPACITY) and grow with the configuration, far below 64 MiB.
MAX_STATE_OBJECTS = 65_536
MAX_STATE_REGION = 64 * 1024 * 1024


def words_to_be(buf: bytes | bytearray | memoryview) -> bytes:
    """Native unsigned 16-bit words -> big-endian bytes (Modbus and state-file order)."""
    a = array("H", bytes(buf))
    if _SWAP:
        a.byteswap()
    return a.tobytes()


def be_to_words(data: bytes | bytearray) -> bytes:
    """Big-endian 16-bit words -> native words."""
    return words_to_be(data)  # a byte swap is its own inverse


@dataclass
class RetainedState:
    """What survives a restart. `capture` takes it between two scans."""

    profile: str
    mw: bytes  # native-order words, as in `MemoryImage.mw.buf`
    m: bytes
    blocks: dict[str, dict[int, Any]] = field(default_factory=dict)
    app: bytes = b""  # `application_id` of the program and configuration that saved it


def application_id(program: bytes, config: dict[str, Any]) -> bytes:
    """What makes an application (as a TwidoSuite download): the program text and the
    controller configuration. The daemon's own settings (`[daemon]`, `[modbus]`) and the
    simulated machine (`[devices]`) are not part of it."""
    app_cfg = {k: v for k, v in config.items() if k not in ("daemon", "modbus", "devices")}
    h = hashlib.sha256(program)
    h.update(json.dumps(app_cfg, sort_keys=True, default=str).encode())
    return h.digest()


# Format 2 files written before timers saved their elapsed time hold `_t0`, the start time
# relative to the clock at saving (= minus the elapsed time): still restored.
_OLD_T0 = "_t0"


def _set_block_state(block: Any, st: dict[str, Any]) -> None:
    if _OLD_T0 in st:
        st = dict(st)
        st["_elapsed_us"] = -st.pop(_OLD_T0)
    block.set_state(st)


def capture_blocks(mem: MemoryImage) -> dict[str, dict[int, Any]]:
    return {kind: {i: b.state() for i, b in d.items()}
            for kind, d in mem.blocks.items() if d}


def capture(mem: MemoryImage, app: bytes = b"") -> RetainedState:
    """Copy the retained objects out of the image (cheap: call it between scans)."""
    return RetainedState(mem.profile.name, bytes(mem.mw.buf), bytes(mem.m),
                         capture_blocks(mem), app)


def apply(mem: MemoryImage, state: RetainedState) -> None:
    """Put a retained state back into the image. Blocks no longer configured are skipped."""
    mem.mw.buf[:] = state.mw
    mem.m[:] = map(bool, state.m)  # the bit image holds bools
    for kind, d in state.blocks.items():
        present = mem.blocks.get(kind, {})
        for i, st in d.items():
            if i in present:
                try:
                    _set_block_state(present[i], st)
                except (TypeError, ValueError, KeyError, AttributeError) as e:
                    raise StateFileError(f"the saved state of %{kind}{i} cannot be "
                                         f"restored ({type(e).__name__}: {e}){_HINT}") from None


def encode_blocks(blocks: dict[str, dict[int, Any]]) -> bytes:
    return json.dumps({k: {str(i): st for i, st in d.items()} for k, d in blocks.items()},
                      separators=(",", ":"), default=_jsonable).encode()


def _bounded_int(text: str) -> int:
    check_digits(text)  # before int(): a crafted 5,000-digit number is a ValueError there
    return int(text)


def _no_constant(text: str) -> float:
    raise BoundsError(f"{text} in a block's state (a finite number is expected)")


def _jsonable(o: Any) -> Any:
    if isinstance(o, bytes | bytearray | memoryview):
        return list(bytes(o))
    if hasattr(o, "tolist"):  # numpy arrays and scalars
        return o.tolist()
    if isinstance(o, set | frozenset):
        return sorted(o)
    raise TypeError(f"cannot retain a {type(o).__name__}")


def _round_page(n: int) -> int:
    return -(-n // PAGE) * PAGE


@dataclass(frozen=True)
class _Layout:
    profile: str
    n_regs: int
    n_coils: int
    blocks_cap: int
    journal_cap: int = JOURNAL_CAPACITY

    @property
    def slot_size(self) -> int:
        return _round_page(_SLOT.size + 2 * self.n_regs + self.n_coils + self.blocks_cap)

    def slot_offset(self, i: int) -> int:
        return PAGE + i * self.slot_size

    @property
    def journal_offset(self) -> int:
        return self.slot_offset(4)

    @property
    def file_size(self) -> int:
        return self.journal_offset + _round_page(self.journal_cap)

    def header(self) -> bytes:
        fields = (MAGIC, FORMAT_VERSION, self.n_regs, self.n_coils, self.blocks_cap,
                  self.journal_cap, self.profile.encode()[:32])
        crc = zlib.crc32(_HEADER.pack(*fields, 0)[:-4])
        return _HEADER.pack(*fields, crc)


def open_locked(path: str | os.PathLike[str], what: str,
                error: type[SoftPLCError] = SoftPLCError,
                holder: Callable[[int], str] = lambda fd: "; choose another file",
                follow_symlinks: bool = True, symlink_hint: str = "") -> int:
    """Open `path` read-write (created if absent, never truncated) and `flock` it for as
    long as the descriptor stays open; `error` if another process holds it (`holder(fd)`
    adds who and what to do), or if it is a symbolic link and not `follow_symlinks`."""
    flags = os.O_RDWR | os.O_CREAT | os.O_CLOEXEC
    if not follow_symlinks:
        flags |= os.O_NOFOLLOW
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as e:
        if e.errno == errno.ELOOP and not follow_symlinks and os.path.islink(path):
            raise error(f"{what} {path} is a symbolic link (to {_link_target(path)}): "
                        f"refused, since a cold start would overwrite what it points to"
                        f"{symlink_hint}") from None
        raise error(f"cannot open {what} {path}: {e.strerror or e}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        busy = e.errno in (errno.EWOULDBLOCK, errno.EAGAIN)
        why = holder(fd) if busy else ""
        os.close(fd)
        if busy:
            raise error(f"{what} {path} is in use by another softplc{why}") from None
        raise error(f"cannot lock {what} {path}: {e.strerror or e}") from None
    return fd


class StateStore:
    """One retained-state file, locked, mapped and kept current by its user.

    `open` locks the file (a second daemon on it gets a clear error), `load` reads what
    the last run left, `start` lays the file out for this controller; then `commit` at
    every scan boundary (image with the acknowledged writes laid over it), `journal`
    before a write is acknowledged, `persist` every save interval, `close` at the end.
    `commit`, `journal` and `persist` may be called from different threads.
    """

    def __init__(self, path: str | os.PathLike[str], fd: int, follow_symlinks: bool = False):
        self.path = Path(path)
        self._fd = fd
        self.follow_symlinks = follow_symlinks
        self._mm: mmap.mmap | None = None
        self._layout: _Layout | None = None
        self._lock = threading.Lock()
        self.seq = 0  # of the newest slot
        self._slot = 0  # newest slot written (or loaded)
        self._jpos = 0
        self._blocks = b"{}"  # blocks JSON of the newest scan-boundary commit
        self.app = b""
        self.persisted_seq = 0
        self.commits = 0
        self._loaded = False  # load() succeeded: self.seq is the newest slot's
        self._durable_seq = [0, 0]  # of the durable slots (0: none that verifies)

    # -- opening -------------------------------------------------------------------------
    @classmethod
    def open(cls, path: str | os.PathLike[str], follow_symlinks: bool = False) -> StateStore:
        """Open (create if absent) and lock. Nothing in the file is changed here. A symbolic
        link is refused unless `follow_symlinks`."""
        return cls(path, _open_state(path, follow_symlinks), follow_symlinks)

    def check(self) -> str:
        """"" while the file at the path is the one this store holds locked; else what
        became of it (someone deleted, moved or replaced it: it will not be read at the
        next start)."""
        try:
            st = os.stat(self.path, follow_symlinks=self.follow_symlinks)
        except FileNotFoundError:
            return "was deleted (or moved away)"
        except OSError as e:
            return f"cannot be checked ({e.strerror or e})"
        me = os.fstat(self._fd)
        if (st.st_dev, st.st_ino) != (me.st_dev, me.st_ino):
            return "was replaced by another file"
        return ""

    def recreate(self) -> None:
        """Write the whole mapped file (every slot and the journal: all that was
        acknowledged) to the path again, locked, and go on in it; the old one is let go.
        StateFileError if it cannot be done (e.g. another softplc took the path, or the
        folder is gone): then nothing is kept at the path."""
        fd = _open_state(self.path, self.follow_symlinks)
        try:
            with self._lock:  # no commit or journal entry meanwhile
                mm = self._mm
                assert mm is not None
                data = mm[:]
                os.ftruncate(fd, 0)
                os.posix_fallocate(fd, 0, len(data))
                view = memoryview(data)
                while view:
                    view = view[os.pwrite(fd, view, len(data) - len(view)):]
                new = mmap.mmap(fd, len(data), mmap.MAP_SHARED,
                                mmap.PROT_READ | mmap.PROT_WRITE)
                old_fd, self._mm, self._fd = self._fd, new, fd
        except OSError as e:
            os.close(fd)
            raise StateFileError(f"cannot re-create state file {self.path}: "
                                 f"{e.strerror or e}") from None
        mm.close()
        os.close(old_fd)
        try:  # outside the lock: scans and writes go on meanwhile
            os.fsync(fd)
        except OSError as e:  # in the page cache all the same: kept through a process kill
            log.error("%s: re-created, but cannot flush it to disk: %s", self._where(),
                      e.strerror or e)
        _fsync_dir(self.path.parent)

    def _where(self) -> str:
        return f"state file {self.path}"

    def load(self) -> RetainedState | None:
        """What the last run left (newest verified slot + its journal); None for a new
        file. Raises StateFileError for anything else that cannot be used."""
        size = os.fstat(self._fd).st_size
        if size == 0:
            return None
        where = self._where()
        head = os.pread(self._fd, _HEADER.size, 0)
        if len(head) < _HEADER.size or not head.startswith(MAGIC[:14]):
            raise StateFileError(f"{where} is not a softplc state file{_HINT}")
        magic, version, n_regs, n_coils, blocks_cap, journal_cap, prof, crc = \
            _HEADER.unpack(head)
        if magic != MAGIC or version != FORMAT_VERSION:
            found = head[14:16].strip().decode(errors="replace") or "?"
            raise StateFileError(f"{where} has format version {found}; this softplc reads "
                                 f"version {FORMAT_VERSION}{_HINT}")
        if zlib.crc32(head[:-4]) != crc:
            raise StateFileError(f"{where} has a corrupt header (checksum mismatch){_HINT}")
        if max(n_regs, n_coils) > MAX_STATE_OBJECTS or \
                max(blocks_cap, journal_cap) > MAX_STATE_REGION:
            raise StateFileError(f"{where} claims {n_regs} registers, {n_coils} coils, "
                                 f"{blocks_cap} + {journal_cap} bytes of blocks and journal: "
                                 f"beyond {MAX_STATE_OBJECTS} objects or "
                                 f"{MAX_STATE_REGION // 2**20} MiB{_HINT}")
        lay = _Layout(prof.rstrip(b"\0").decode(errors="replace"), n_regs, n_coils,
                      blocks_cap, journal_cap)
        if size != lay.file_size:
            raise StateFileError(f"{where} is truncated or padded ({size} of {lay.file_size} "
                                 f"bytes){_HINT}")
        self._map(lay)
        best = self._newest_slot()
        if best is None:
            raise StateFileError(f"{where} is corrupt (no copy of the data passes its "
                                 f"checksum){_HINT}")
        seq, off, app, blen = best
        mm = self._mm
        assert mm is not None
        p = off + _SLOT.size
        regs = bytearray(mm[p:p + 2 * n_regs])
        p += 2 * n_regs
        coils = bytearray(mm[p:p + n_coils])
        p += n_coils
        try:
            raw = json.loads(mm[p:p + blen], parse_int=_bounded_int,
                             parse_constant=_no_constant)
            blocks = {str(k): {int(_bounded_int(i)): dict(st) for i, st in v.items()}
                      for k, v in raw.items()}
        except (ValueError, TypeError, AttributeError, RecursionError, BoundsError) as e:
            raise StateFileError(f"{where} has a valid checksum but unreadable content "
                                 f"({e}){_HINT}") from None
        replayed = self._replay(seq, regs, coils)
        if replayed:
            log.info("%s: %d acknowledged writes replayed from the journal", where, replayed)
        self.seq, self._slot = seq, (off - lay.slot_offset(0)) // lay.slot_size
        self._durable_seq = [self._slot_seq(i) for i in DURABLE]
        self.app = app
        self._loaded = True
        return RetainedState(lay.profile, be_to_words(regs), bytes(coils), blocks, app)

    def _map(self, lay: _Layout) -> None:
        if self._mm is not None:
            self._mm.close()
        self._layout = lay
        self._mm = mmap.mmap(self._fd, lay.file_size, mmap.MAP_SHARED,
                             mmap.PROT_READ | mmap.PROT_WRITE)

    def _newest_slot(self) -> tuple[int, int, bytes, int] | None:
        lay, mm = self._layout, self._mm
        assert lay is not None and mm is not None
        best = None
        damaged = 0  # highest seq claimed by a slot that does not verify
        for i in (*VOLATILE, *DURABLE):
            seq = self._slot_seq(i)
            off = lay.slot_offset(i)
            if not seq:
                damaged = max(damaged, _SLOT.unpack_from(mm, off)[0])
            elif best is None or seq > best[0]:
                _seq, app, blen, _crc = _SLOT.unpack_from(mm, off)
                best = (seq, off, app, blen)
        if best is not None and damaged > best[0]:
            # (a commit cut off by a kill still carries its slot's older seq: no warning)
            log.warning("%s: a newer copy of the data (%d) is damaged; using copy %d",
                        self._where(), damaged, best[0])
        return best

    def _replay(self, gen: int, regs: bytearray, coils: bytearray) -> int:
        lay, mm = self._layout, self._mm
        assert lay is not None and mm is not None
        pos, end, n = lay.journal_offset, lay.journal_offset + lay.journal_cap, 0
        while pos + _ENTRY.size <= end:
            g, space, addr, length, crc = _ENTRY.unpack_from(mm, pos)
            data = mm[pos + _ENTRY.size: pos + _ENTRY.size + length]
            if g != gen or len(data) != length or \
                    zlib.crc32(data, zlib.crc32(mm[pos:pos + _ENTRY.size - 4])) != crc:
                break
            if space == REGISTERS and 2 * addr + length <= len(regs):
                regs[2 * addr: 2 * addr + length] = data
            elif space == COILS and addr + length <= len(coils):
                coils[addr: addr + length] = data
            else:
                break
            pos += _ENTRY.size + length
            n += 1
        return n

    def start(self, state: RetainedState) -> None:
        """Lay the file out for the controller `state` comes from (its starting image),
        keeping what `load` read if the layout fits (new commits win: their seq is
        higher), and commit `state`."""
        blocks = encode_blocks(state.blocks)
        want = _Layout(state.profile, len(state.mw) // 2, len(state.m),
                       max(BLOCKS_MIN_CAPACITY, _round_page(8 * len(blocks))))
        lay = self._layout
        self.app = state.app
        self._blocks = blocks
        if self._loaded and lay is not None and (lay.profile, lay.n_regs, lay.n_coils) == (
                want.profile, want.n_regs, want.n_coils) and lay.blocks_cap >= 2 * len(blocks):
            self.commit(words_to_be(state.mw), state.m, blocks)
            return
        if self._mm is not None:
            self._mm.close()
            self._mm = None
        try:
            os.ftruncate(self._fd, 0)  # no stale slot may survive a new layout
            os.posix_fallocate(self._fd, 0, want.file_size)  # no SIGBUS on a full disk
            os.pwrite(self._fd, want.header(), 0)
            os.fsync(self._fd)
        except OSError as e:
            raise StateFileError(f"cannot write state file {self.path}: "
                                 f"{e.strerror or e}") from None
        _fsync_dir(self.path.parent)
        self._map(want)
        self.seq = 0
        self._durable_seq = [0, 0]
        self.commit(words_to_be(state.mw), state.m, blocks)

    # -- running -------------------------------------------------------------------------
    def set_pid(self) -> None:
        os.pwrite(self._fd, _PID.pack(os.getpid()), _PID_OFFSET)

    def commit(self, regs_be: bytes, coils: bytes, blocks: bytes | None = None) -> None:
        """Write a new volatile slot: %MW (big-endian), %M (one byte each) and the blocks'
        JSON (None: the last one). Empties the journal, whose writes it includes."""
        lay = self._layout
        with self._lock:
            mm = self._mm  # under the lock: `recreate` replaces it
            assert lay is not None and mm is not None
            if blocks is None:
                blocks = self._blocks
            elif len(blocks) > lay.blocks_cap:
                raise StateFileError(f"{self._where()}: the blocks' state ({len(blocks)} bytes) "
                                     f"outgrew the file's {lay.blocks_cap}; restart to resize")
            else:
                self._blocks = blocks
            seq = self.seq + 1
            slot = VOLATILE[seq & 1]
            off = lay.slot_offset(slot)
            p = off + _SLOT.size
            mm[p:p + len(regs_be)] = regs_be
            p += len(regs_be)
            mm[p:p + len(coils)] = coils
            p += len(coils)
            mm[p:p + len(blocks)] = blocks
            head = _SLOT.pack(seq, self.app, len(blocks), 0)[:-4]
            crc = zlib.crc32(blocks, zlib.crc32(coils, zlib.crc32(regs_be, zlib.crc32(head))))
            mm[off:off + _SLOT.size] = head + struct.pack("<I", crc)  # last: validates it
            self.seq, self._slot, self._jpos = seq, slot, 0
            self.commits += 1

    def journal(self, space: int, addr: int, data: bytes) -> bool:
        """Append an acknowledged write (registers big-endian; coils one byte each).
        False when the journal is full: commit a slot that includes the write instead."""
        lay = self._layout
        with self._lock:
            mm = self._mm  # under the lock: `recreate` replaces it
            assert lay is not None and mm is not None
            pos = lay.journal_offset + self._jpos
            size = _ENTRY.size + len(data)
            if self._jpos + size > lay.journal_cap:
                return False
            head = _ENTRY.pack(self.seq, space, addr, len(data), 0)[:-4]
            mm[pos + _ENTRY.size: pos + size] = data
            mm[pos:pos + _ENTRY.size] = head + struct.pack("<I", zlib.crc32(data, zlib.crc32(head)))
            self._jpos += size
            return True

    def _slot_seq(self, i: int) -> int:
        """Seq of slot i if it verifies, else 0."""
        lay, mm = self._layout, self._mm
        assert lay is not None and mm is not None
        off = lay.slot_offset(i)
        seq, _app, blen, crc = _SLOT.unpack_from(mm, off)
        if seq == 0 or blen > lay.blocks_cap:
            return 0
        body = mm[off + _SLOT.size: off + _SLOT.size + 2 * lay.n_regs + lay.n_coils + blen]
        ok = zlib.crc32(body, zlib.crc32(mm[off:off + _SLOT.size - 4])) == crc
        return seq if ok else 0

    def persist(self) -> None:
        """Copy the newest slot over the older durable one and msync it (power-loss
        safety): the newer durable copy stays intact meanwhile. One thread at a time, the
        one that may `recreate`; the disk write happens outside the commit lock."""
        lay, mm = self._layout, self._mm
        assert lay is not None and mm is not None
        k = 0 if self._durable_seq[0] <= self._durable_seq[1] else 1
        dst = lay.slot_offset(DURABLE[k])
        with self._lock:
            if self.seq == self.persisted_seq:
                return
            src = lay.slot_offset(self._slot)
            used = _SLOT.size + 2 * lay.n_regs + lay.n_coils + _SLOT.unpack_from(mm, src)[2]
            mm[dst:dst + used] = mm[src:src + used]
            seq = self.seq
        mm.flush(dst, lay.slot_size)
        self._durable_seq[k] = self.persisted_seq = seq

    def close(self) -> None:
        """msync everything and unlock."""
        if self._mm is not None:
            self._mm.flush()
            self._mm.close()
            self._mm = None
        if self._fd >= 0:
            os.close(self._fd)  # releases the flock
            self._fd = -1


def _link_target(path: str | os.PathLike[str]) -> str:
    try:
        return os.readlink(path)
    except OSError:
        return "?"


def _open_state(path: str | os.PathLike[str], follow_symlinks: bool) -> int:
    def holder(fd: int) -> str:
        pid = _PID.unpack(os.pread(fd, _PID.size, _PID_OFFSET).ljust(_PID.size, b"\0"))[0]
        return (f" (pid {pid})" if pid else "") + (
            ": two controllers on one state file would overwrite each other's data; stop "
            "it or use another --state file")

    return open_locked(path, "state file", StateFileError, holder, follow_symlinks,
                       "; --state-symlink allows it")


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems cannot fsync a directory
    finally:
        os.close(fd)


def check_compatible(state: RetainedState, mem: MemoryImage, where: str = "state file") -> None:
    if state.profile != mem.profile.name or len(state.mw) != len(mem.mw.buf) \
            or len(state.m) != len(mem.m):
        raise StateFileError(
            f"{where} was saved by a {state.profile} with {len(state.mw) // 2} %MW and "
            f"{len(state.m)} %M; this controller is a {mem.profile.name} with {mem.mw.n} %MW "
            f"and {len(mem.m)} %M{_HINT}")


def restart(plc: Any, state: RetainedState | None, *, cold: bool = False,
            keep_state: bool = False, app: bytes = b"", where: str = "state file"
            ) -> tuple[str, str]:
    """Warm restart from `state` if it belongs to this application, else cold start.

    Returns ("warm" or "cold", why). A state saved by another program or configuration is
    a new application: cold start, as a Twido after a download, unless `keep_state`.
    """
    if cold:
        plc.cold_start()
        return "cold", "--cold"
    if state is None:
        plc.cold_start()
        return "cold", "no retained state yet"
    check_compatible(state, plc.mem, where)
    if app and state.app != app:
        if not keep_state:
            plc.cold_start()
            return "cold", ("the program or configuration changed since the state was saved "
                            "(a new application); --keep-state keeps the data")
        why = "program or configuration changed, data kept (--keep-state)"
    else:
        why = "same program and configuration"
    apply(plc.mem, state)
    plc.warm_start()
    return "warm", why


def save(path: str | os.PathLike[str], state: RetainedState) -> None:
    """Write `state` to `path` (tools and tests; the daemon keeps its store open)."""
    store = StateStore.open(path)
    try:
        try:
            store.load()
        except StateFileError:
            pass  # replaced as a whole
        store.start(state)
        store.persist()
    finally:
        store.close()


def load(path: str | os.PathLike[str]) -> RetainedState | None:
    """Read a state file; None if it does not exist (or was never written)."""
    if not Path(path).exists():
        return None
    store = StateStore.open(path)
    try:
        return store.load()
    finally:
        store.close()
