"""Live values for the ladder view: memory, the rung's accumulator log, forced objects."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from softplc.il import ast as A
from softplc.il import rungtree
from softplc.il.printer import format_expr
from softplc.ladder.tree import BOX_PINS, Elem, element, short_form_block
from softplc.twido.address import Ref
from softplc.twido.display import format_value
from softplc.twido.semantics import COMPARE


class Live:
    """What the live view reads: memory, the rung's accumulator log, forced objects."""

    def __init__(self, read: Callable[[Ref], Any], log: list[Any] | None,
                 forced: set[str] | None = None):
        self.read = read
        self.log = log
        self.forced = forced or set()

    def acc(self, k: int) -> bool | None:
        if self.log is None or not 0 <= k < len(self.log):
            return None
        return bool(self.log[k])

    def value(self, ref: Ref | None) -> str:
        if ref is None:
            return ""
        try:
            v = self.read(ref)
        except Exception:  # an unconfigured block and the like: show nothing
            return "?"
        return format_value(v, ref) + ("F" if str(ref) in self.forced else "")

    def expr_text(self, e: A.Expr) -> str:
        """An expression with its objects replaced by their values."""
        if isinstance(e, A.Addr):
            return self.value(e.ref)
        if isinstance(e, A.BinOp):
            return f"{self.expr_text(e.left)} {e.op} {self.expr_text(e.right)}"
        if isinstance(e, A.Neg):
            return f"-{self.expr_text(e.operand)}"
        return format_expr(e)

    def closed(self, el: Elem) -> bool | None:
        """Whether a contact passes power (None: cannot tell)."""
        ins = el.instr
        if isinstance(ins, A.ParenOpen) or (el.op == "LD" and self.log is not None):
            return self.acc(el.k)
        if el.op == "AND" and self.acc(el.k):
            return True
        if el.op == "OR" and self.acc(el.k - 1) is False:
            return self.acc(el.k)
        op = getattr(ins, "operand", None)
        mod = getattr(ins, "modifier", "")
        if isinstance(op, A.Const):
            return bool(op.value)
        if isinstance(op, A.Compare):
            vals = []
            for side in (op.left, op.right):
                if isinstance(side, A.Num):
                    vals.append(side.value)
                elif isinstance(side, A.Addr):
                    try:
                        vals.append(self.read(side.ref))
                    except Exception:
                        return None
                else:
                    return None
            a, b = vals
            r = COMPARE[op.op](a, b)
            return (not r) if mod == "N" else r
        if el.ref is not None and mod in ("", "N"):
            try:
                v = bool(self.read(el.ref))
            except Exception:
                return None
            return v != (mod == "N")
        return None


def _expr_refs(e: A.Expr) -> list[Ref]:
    """The objects `Live.expr_text` shows the values of (those under + - * / and -x)."""
    if isinstance(e, A.Addr):
        return [e.ref]
    if isinstance(e, A.BinOp):
        return _expr_refs(e.left) + _expr_refs(e.right)
    if isinstance(e, A.Neg):
        return _expr_refs(e.operand)
    return []


def reads(rung: A.Rung) -> list[Ref]:
    """The objects the live view of `rung` reads, in instruction order, from the rung's
    structure (`il/rungtree.py`) without drawing it: what each instruction's element shows
    (a contact's bit, a comparison's operands, a coil's or an operation's target, the block
    of a short-form input) and each box, BLK or short-form (the block, its output pins)."""
    seen: dict[Ref, None] = {}
    for st in rungtree.build(rung).steps:
        if not st.ok:
            continue
        b = st.block if isinstance(st.instr, A.Blk) else short_form_block(st)
        if b is not None:  # a box: the block and its output pins
            seen[Ref(b.kind, b.index)] = None
            seen.update((Ref(b.kind, b.index, field=pin), None)
                        for pin in BOX_PINS.get(b.kind, ((), ()))[1])
            continue
        el = element(st)
        if el is None:
            continue
        cmp_ = getattr(el.instr, "operand", None)
        if el.kind == "compare" and isinstance(cmp_, A.Compare):
            seen.update((r, None) for r in _expr_refs(cmp_.left) + _expr_refs(cmp_.right))
        elif el.ref is not None:
            seen[el.ref] = None
    return list(seen)


def block_summary(b: Any) -> str:
    """A function block's fields in one short string."""
    parts = []
    # a block class may name its own fields (%VFC: thresholds, capture...)
    for f in getattr(b, "SUMMARY", ("Q", "V", "P", "D", "E", "F", "S", "W")):
        if hasattr(b, f) and not callable(getattr(b, f)):
            parts.append(f"{f}={int(getattr(b, f))}")
    return " ".join(parts)
