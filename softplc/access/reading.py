"""Typed reads of a running controller, taken in the scan thread at a scan boundary.

One JSON type per object type, whatever path a value takes: bits are 0/1 (int, never
true/false: compiled code may store a bool in a bit list), words and double words int,
floats float, a function block a dict of its fields by their types (`BLOCK_FIELDS`: bits
0/1, words int), None for an object that cannot be read.

`Reading.sample(fn)` runs `fn` right after the next scan (an `after_scan` hook), so a
read is the values of one scan, never a half-finished one; `reader` builds the function
that reads a list of objects there cheaply.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

from softplc.errors import SoftPLCError
from softplc.twido.address import Ref
from softplc.twido.display import block_fields

SAMPLE_WAIT = 0.25  # s: longer than that without a scan (long period, stopped loop): read now


class _Sample:
    """A function to run in the scan thread at the end of a scan, and its result handed to
    the event loop waiting for it. Runs once, whichever thread gets to it first."""

    def __init__(self, fn: Callable[[], Any], loop: asyncio.AbstractEventLoop,
                 future: asyncio.Future):
        self.fn = fn
        self.loop = loop
        self.future = future
        self.lock = threading.Lock()
        self.taken = False

    def run(self) -> None:
        with self.lock:
            if self.taken:
                return
            self.taken = True
        try:
            result, error = self.fn(), None
        except BaseException as e:  # handed to the waiting request
            result, error = None, e
        try:
            self.loop.call_soon_threadsafe(self._deliver, result, error)
        except RuntimeError:  # the loop is closed: nobody waits any more
            pass

    def _deliver(self, result: Any, error: BaseException | None) -> None:
        if self.future.done():
            return
        if error is not None:
            self.future.set_exception(error)
        else:
            self.future.set_result(result)


class Reading:
    def __init__(self, plc: Any):
        self.plc = plc
        self._samples: deque[_Sample] = deque()
        self._readers: dict[Any, Callable[[], list[Any]]] = {}

    def serve(self) -> None:
        """after_scan hook (scan thread)."""
        q = self._samples
        while q:
            q.popleft().run()

    async def sample(self, fn: Callable[[], Any]) -> Any:
        """Run `fn` in the scan thread right after the next scan (or here, if no scan comes
        within SAMPLE_WAIT) and return its result."""
        loop = asyncio.get_running_loop()
        s = _Sample(fn, loop, loop.create_future())
        self._samples.append(s)
        try:
            return await asyncio.wait_for(asyncio.shield(s.future), SAMPLE_WAIT)
        except TimeoutError:
            s.run()  # nothing if the scan thread took it meanwhile
            return await s.future

    def values_fn(self, refs: list[tuple[str, Ref]]) -> Callable[[], dict[str, Any]]:
        """A function giving {name: value} of `refs`: prepare it here (in the front-end's thread),
        call it in the scan thread (`sample`), where it costs little."""
        reader = self.reader([r for _, r in refs])
        names = [n for n, _ in refs]
        return lambda: dict(zip(names, reader(), strict=True))

    def read_one(self, ref: Ref) -> Any:
        """One typed value (module docstring) through `MemoryImage.read`."""
        try:
            v = self.plc.mem.read(ref)
        except SoftPLCError:
            return None
        if isinstance(v, bool):
            return int(v)
        return block_fields(ref.kind, v) if ref.is_block else v

    def reader(self, refs: list[Ref]) -> Callable[[], list[Any]]:
        """A function that reads `refs` into a list. It runs in the scan thread after a scan,
        ten times a second per page, so plain words and bits are read straight from the
        memory image's arrays (about 50 ns each, where `MemoryImage.read` takes a few us;
        a bit with a unary +: a stored bool reads 0/1); the rest goes through `read_one`.
        An input not yet latched by any scan reads from the field, as `MemoryImage.read`
        does: the reader is rebuilt when that set grows."""
        mem = self.plc.mem
        latched = mem.io_used("I")
        key = (tuple(refs), len(latched))
        fn = self._readers.get(key)
        if fn is not None:
            return fn
        env: dict[str, Any] = {"MW": mem.mw.w, "KW": mem.kw.w, "SW": mem.sw.w, "M": mem.m,
                               "S": mem.s, "X": mem.x, "Q": mem.q, "I": mem.i,
                               "F": mem.i_field, "read": self.read_one, "R": refs}
        items = []
        for k, ref in enumerate(refs):
            plain = ref.offset is None and ref.bit is None and ref.length is None \
                and ref.field is None
            if plain and ref.kind in ("MW", "KW", "SW"):
                items.append(f"{ref.kind}[{ref.index}]")
            elif plain and ref.kind in ("M", "S", "X", "Q"):
                items.append(f"+{ref.kind}[{ref.index}]")
            elif plain and ref.kind == "I":
                items.append(f"+{'I' if ref.index in latched else 'F'}[{ref.index}]")
            else:
                items.append(f"read(R[{k}])")
        exec(f"def reader():\n    return [{', '.join(items)}]\n", env)
        if len(self._readers) > 256:
            self._readers.clear()
        fn = self._readers[key] = env["reader"]
        return fn


__all__ = ["Reading"]
