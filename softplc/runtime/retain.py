"""Retained state: %MW, %M and function-block values kept across restarts (`--state FILE`).

File format (version 1): one ASCII header line, then a JSON body::

    SOFTPLC-STATE 1 <body length> <sha256 of the body, hex>\\n
    {"format": 1, "profile": "TWDLCAE40DRF", "mw": "<base64>", "m": "<base64>",
     "blocks": {"TM": {"0": {...}}, "C": {...}}, "program": "...", "saved": "..."}

The header makes truncation and corruption detectable before anything is parsed. Saving
is atomic: temp file in the same directory, fsync, rename over the old file, fsync of the
directory; a crash at any point leaves either the old or the new file, never a mix.

Starting with a state file that does not exist is a cold start (first run). A file that is
present but unreadable, truncated, corrupt or for another controller is an error unless
the user asks for a cold start: the data is never reset silently.
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import SoftPLCError
from .memory import MemoryImage

log = logging.getLogger("softplc.retain")

MAGIC = "SOFTPLC-STATE"
FORMAT_VERSION = 1
_HINT = "; start with --cold to discard it and cold-start"


class StateFileError(SoftPLCError):
    """A retained-state file cannot be used."""


@dataclass
class RetainedState:
    """What survives a restart. `capture` takes it between two scans."""

    profile: str
    mw: bytes
    m: bytes
    blocks: dict[str, dict[int, Any]] = field(default_factory=dict)
    program: str = ""


# Block state fields holding an absolute clock time (µs): retained relative to the clock,
# since the next run's clock starts again from its own origin.
_TIME_FIELDS = ("_t0",)


def _now_us(block: Any) -> int | None:
    return getattr(getattr(block, "clock", None), "now_us", None)


def _block_state(block: Any) -> dict[str, Any]:
    st = dict(block.state())
    now = _now_us(block)
    if now is not None:
        for f in _TIME_FIELDS:
            if f in st:
                st[f] -= now
    return st


def _set_block_state(block: Any, st: dict[str, Any]) -> None:
    st = dict(st)
    now = _now_us(block)
    if now is not None:
        for f in _TIME_FIELDS:
            if f in st:
                st[f] += now
    block.set_state(st)


def capture(mem: MemoryImage, program: str = "") -> RetainedState:
    """Copy the retained objects out of the image (cheap: call it between scans)."""
    blocks = {kind: {i: _block_state(b) for i, b in d.items()}
              for kind, d in mem.blocks.items() if d}
    return RetainedState(mem.profile.name, bytes(mem.mw.buf), bytes(mem.m), blocks, program)


def apply(mem: MemoryImage, state: RetainedState) -> None:
    """Put a retained state back into the image. Blocks no longer configured are skipped."""
    mem.mw.buf[:] = state.mw
    mem.m[:] = state.m
    for kind, d in state.blocks.items():
        present = mem.blocks.get(kind, {})
        for i, st in d.items():
            if i in present:
                _set_block_state(present[i], st)


def encode(state: RetainedState) -> bytes:
    body = json.dumps({
        "format": FORMAT_VERSION,
        "profile": state.profile,
        "program": state.program,
        "saved": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "mw": base64.b64encode(state.mw).decode(),
        "m": base64.b64encode(state.m).decode(),
        "blocks": {k: {str(i): st for i, st in d.items()} for k, d in state.blocks.items()},
    }, separators=(",", ":"), default=_jsonable).encode()
    header = f"{MAGIC} {FORMAT_VERSION} {len(body)} {hashlib.sha256(body).hexdigest()}\n"
    return header.encode() + body


def _jsonable(o: Any) -> Any:
    if isinstance(o, bytes | bytearray | memoryview):
        return list(bytes(o))
    if hasattr(o, "tolist"):  # numpy arrays and scalars
        return o.tolist()
    if isinstance(o, set | frozenset):
        return sorted(o)
    raise TypeError(f"cannot retain a {type(o).__name__}")


def decode(data: bytes, where: str = "state file") -> RetainedState:
    """Parse and verify a state file's bytes. Raises StateFileError with a clear reason."""
    head, sep, body = data.partition(b"\n")
    parts = head.split()
    if not sep or len(parts) != 4 or parts[0] != MAGIC.encode():
        raise StateFileError(f"{where} is not a softplc state file"
                             f"{' (empty)' if not data else ''}{_HINT}")
    try:
        version, length = int(parts[1]), int(parts[2])
    except ValueError:
        raise StateFileError(f"{where} has a corrupt header{_HINT}") from None
    if version != FORMAT_VERSION:
        raise StateFileError(f"{where} has format version {version}; this softplc reads "
                             f"version {FORMAT_VERSION}{_HINT}")
    if len(body) != length:
        raise StateFileError(f"{where} is truncated or padded ({len(body)} of {length} "
                             f"bytes){_HINT}")
    if hashlib.sha256(body).hexdigest().encode() != parts[3]:
        raise StateFileError(f"{where} is corrupt (checksum mismatch){_HINT}")
    try:
        d = json.loads(body)
        blocks = {k: {int(i): st for i, st in v.items()} for k, v in d["blocks"].items()}
        return RetainedState(d["profile"], base64.b64decode(d["mw"], validate=True),
                             base64.b64decode(d["m"], validate=True), blocks,
                             d.get("program", ""))
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise StateFileError(f"{where} has a valid checksum but unreadable content "
                             f"({e}){_HINT}") from None


def check_compatible(state: RetainedState, mem: MemoryImage, where: str = "state file") -> None:
    if state.profile != mem.profile.name or len(state.mw) != len(mem.mw.buf) \
            or len(state.m) != len(mem.m):
        raise StateFileError(
            f"{where} was saved by a {state.profile} with {len(state.mw) // 2} %MW and "
            f"{len(state.m)} %M; this controller is a {mem.profile.name} with {mem.mw.n} %MW "
            f"and {len(mem.m)} %M{_HINT}")


def save(path: str | os.PathLike[str], state: RetainedState) -> None:
    """Write atomically: temp file, fsync, rename, fsync the directory."""
    path = Path(path)
    data = encode(state)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise StateFileError(f"cannot save state to {path}: {e.strerror or e}") from None
    try:
        fd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems cannot fsync a directory
    finally:
        os.close(fd)


def load(path: str | os.PathLike[str]) -> RetainedState | None:
    """Read a state file; None if it does not exist."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        return None
    except OSError as e:
        raise StateFileError(f"cannot read state file {path}: {e.strerror or e}{_HINT}") from None
    return decode(data, f"state file {path}")


def restart(plc: Any, path: str | os.PathLike[str] | None, cold: bool = False,
            program: str = "") -> str:
    """Warm restart from `path` if it holds a good state, else cold start.

    Returns "warm" or "cold"; raises StateFileError for an unusable file unless `cold`.
    """
    if path is not None and not cold:
        state = load(path)
        if state is not None:
            check_compatible(state, plc.mem, f"state file {path}")
            if program and state.program and state.program != program:
                log.warning("state file %s was saved by %s; warm restart of %s anyway",
                            path, state.program, program)
            apply(plc.mem, state)
            plc.warm_start()
            return "warm"
    plc.cold_start()
    return "cold"


class RetainWriter:
    """Saves states on a background thread, so fsync never delays a scan.

    `submit` replaces any state not yet written (only the newest matters); `close`
    writes what is pending and waits.
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = path
        self._pending: RetainedState | None = None
        self._cv = threading.Condition()
        self._closing = False
        self.saves = 0
        self.error: StateFileError | None = None
        self._thread = threading.Thread(target=self._run, name="retain", daemon=True)
        self._thread.start()

    def submit(self, state: RetainedState) -> None:
        with self._cv:
            self._pending = state
            self._cv.notify()

    def _run(self) -> None:
        while True:
            with self._cv:
                while self._pending is None and not self._closing:
                    self._cv.wait()
                state, self._pending = self._pending, None
                if state is None:
                    return
            try:
                save(self.path, state)
                self.saves += 1
                self.error = None
            except StateFileError as e:
                self.error = e

    def close(self, final: RetainedState | None = None) -> None:
        """Write `final` (or what is pending) and stop. Raises the last save error."""
        with self._cv:
            if final is not None:
                self._pending = final
            self._closing = True
            self._cv.notify()
        self._thread.join()
        if self.error is not None:
            raise self.error
