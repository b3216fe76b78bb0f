"""The function blocks as solver terms: the verifier's side of each family's model.

A family's model (`softplc.blocks.BlockModel`, named by its catalog entry's `verify`) says
what state a block keeps and computes one execution over a value domain; here it gets the
solver's (`symbolic.Z3State`), its fields as the terms of the state being built (key
`%TM0.V`: block `%TM0`, field V), and what it returns is written back guarded by `g`,
whether the block runs. The rule is the one the engine runs or is checked against
(tests/integration/test_block_rules.py), so the verifier has no copy of a block's logic.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import z3

from softplc.blocks import BIT
from softplc.verify.symbolic import If, as_bool

OUT = "out"  # the values of the output bits a block writes (a drum's), in the view and result


def sort_name(width: int) -> str:
    """A block field's sort in `model.sort_of` terms: bool, w16 or bvN."""
    return "bool" if width == BIT else "w16" if width == 16 else f"bv{width}"


def view(st: dict[str, Any], name: str, fields: Sequence[str],
         outs: Sequence[str] = ()) -> dict[str, Any]:
    """Block `name`'s fields as a model's `s` (its output bits' values under OUT)."""
    s = {f: st[f"{name}.{f}"] for f in fields}
    if outs:
        s[OUT] = [st[k] for k in outs]
    return s


def _set(st: dict[str, Any], key: str, g: Any, value: Any) -> None:
    old = st[key]
    if z3.is_bool(old):
        value = as_bool(value)
        st[key] = If(g, value, old) if not z3.is_true(g) else value
    else:
        v = value if not isinstance(value, int) else z3.BitVecVal(value, old.size())
        if z3.is_bv(v) and v.size() != old.size():
            v = z3.Extract(old.size() - 1, 0, v)
        st[key] = If(g, v, old) if not z3.is_true(g) else v
    st[key] = z3.simplify(st[key])


def apply(st: dict[str, Any], name: str, g: Any, new: dict[str, Any],
          outs: Sequence[str] = ()) -> None:
    """Write what a model's `run` (or `set_bit`, `after_scan`) returned, where g holds."""
    for f, v in new.items():
        if f == OUT:
            for key, x in zip(outs, v, strict=True):
                _set(st, key, g, x)
        else:
            _set(st, f"{name}.{f}", g, v)

