"""Addresses the access port accepts: text -> single objects, with a clear error, and the
count of a list checked before any range is expanded."""

from __future__ import annotations

from typing import Any

from softplc.access.errors import AccessError
from softplc.errors import AddressError
from softplc.twido.address import BLOCK_FIELDS, Ref, expand, parse_address

MAX_OBJECTS = 2000  # objects one read or page may name (counted before expanding ranges)
REF_CACHE = 20000  # single objects kept by the address cache (over all its keys)


class Objects:
    def __init__(self, plc: Any):
        self.plc = plc
        self.profile = plc.profile
        self._refs: dict[str, list[Ref]] = {}
        self._cached_refs = 0  # single objects in self._refs

    def resolve(self, text: Any) -> list[Ref]:
        """An address, range or symbol -> single objects, with a clear error for anything
        else."""
        if not isinstance(text, str) or not text.strip():
            raise AccessError(f"object {text!r}: expected an address like %MW3, %MW0:10, "
                              "%I0.0")
        key = text.strip().upper()
        refs = self._refs.get(key)
        if refs is None:
            try:  # an address, or a symbol of the configuration (softplc.twido.symbols)
                table = self.plc.symbols  # symbols attached: messages name them
                refs = [table.attach(r) for r in expand(table.address_of(key), self.profile)]
            except AddressError as e:
                raise AccessError(f"unknown object {text!r}: {e}") from None
            for r in refs:
                if r.kind in BLOCK_FIELDS and r.index not in self.plc.mem.blocks[r.kind]:
                    raise AccessError(f"unknown object {text!r}: %{r.kind}{r.index} is not "
                                   f"configured or used by the program")
            if self._cached_refs + len(refs) <= REF_CACHE:
                self._refs[key] = refs
                self._cached_refs += len(refs)
        return refs

    def address_of(self, text: Any) -> str:
        """The canonical address a text names (`%MW10:2` for `starts:2`), checked as a read
        would check it: how the web page turns what a user typed into a table's row, by
        the one resolver (softplc.twido.symbols)."""
        self.resolve(text)
        return str(parse_address(self.plc.symbols.address_of(text.strip()), self.profile))

    def forget(self) -> None:
        """Drop the cached addresses (after a program or symbol change)."""
        self._refs.clear()
        self._cached_refs = 0

    def check_count(self, texts: list[Any]) -> None:
        """Refuse a list naming more than MAX_OBJECTS objects, counted before any range is
        expanded (a 64 KiB list of ranges would otherwise expand to millions)."""
        n = len(texts)
        if n <= MAX_OBJECTS:
            n = 0
            for text in texts:
                n += self._count(text)
                if n > MAX_OBJECTS:
                    break
        if n > MAX_OBJECTS:
            raise AccessError(f"more than {MAX_OBJECTS} objects in one request or page: "
                           f"at most {MAX_OBJECTS}")

    def _count(self, text: Any) -> int:
        """How many objects `text` names (1 for anything `resolve` will refuse)."""
        if not isinstance(text, str):
            return 1
        key = text.strip().upper()
        refs = self._refs.get(key)
        if refs is not None:
            return len(refs)
        try:
            return parse_address(self.plc.symbols.address_of(key), self.profile).length or 1
        except AddressError:
            return 1

    def resolve_many(self, texts: Any) -> list[tuple[str, Ref]]:
        if isinstance(texts, str):
            texts = [texts]
        if not isinstance(texts, list) or not texts:
            raise AccessError("objects: expected a list of addresses")
        self.check_count(texts)
        out = [(str(r), r) for t in texts for r in self.resolve(t)]
        if len(out) > MAX_OBJECTS:
            raise AccessError(f"{len(out)} objects in one read: at most {MAX_OBJECTS}")
        return out


__all__ = ["MAX_OBJECTS", "Objects"]
