"""One text for each kind of value, shared by every place that shows one: `softplc io`, the
debugger (`print`, `watch`, `history`) and the ladder views. A bit reads 1 or 0 everywhere
(never True/False, whether it comes from the memory image, numpy or the web API's JSON), a
float shows 7 significant digits (what a 32-bit float holds), a function block shows as
`TON base 100ms Q=0 V=3 P=50` (never a Python dict).

Light on purpose (no numpy, no PLC): `softplc io` imports it on a machine without the
daemon's dependencies loaded.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from softplc.twido.address import BLOCK_FIELDS, Ref


def block_fields(kind: str, b: Any) -> dict[str, Any]:
    """A function block's fields (those the program can name, plus a timer's type and time
    base) as a dict: what the web API sends and what `format_block` shows."""
    out: dict[str, Any] = {f: int(getattr(b, f)) for f in BLOCK_FIELDS[kind] if hasattr(b, f)}
    for extra in ("type", "base"):
        if hasattr(b, extra):
            out[extra] = str(getattr(b, extra))
    return out


def format_block(fields: Mapping[str, Any]) -> str:
    """`{'Q': 0, 'V': 3, 'P': 50, 'type': 'TON', 'base': '100ms'}` -> `TON base 100ms Q=0
    V=3 P=50`."""
    head = [str(fields["type"])] if "type" in fields else []
    if "base" in fields:
        head += ["base", str(fields["base"])]
    body = [f"{k}={format_value(v)}" for k, v in fields.items() if k not in ("type", "base")]
    return " ".join(head + body)


def _is_bit(value: Any) -> bool:
    # bool, numpy.bool_ (a memory image's bit arrays) without importing numpy
    return isinstance(value, bool) or getattr(getattr(value, "dtype", None), "kind", "") == "b"


def format_value(value: Any, ref: Ref | None = None) -> str:
    """`value` as the user sees it; `ref` (the object it was read from) tells a bit stored
    as an integer (0/1 from the web API) and a function block apart."""
    if value is None:
        return "?"  # an object that cannot be read (the API's null)
    if isinstance(value, Mapping):
        return format_block(value)
    if ref is not None and ref.is_block and ref.field is None:
        return format_block(block_fields(ref.kind, value))
    if _is_bit(value) or (ref is not None and ref.type == "bool"):
        return "1" if value else "0"
    if isinstance(value, float) or getattr(getattr(value, "dtype", None), "kind", "") == "f":
        return f"{float(value):.7g}"
    if isinstance(value, int) or hasattr(value, "dtype"):
        return str(int(value))
    return str(value)
