"""Instruction List rungs drawn as ladder diagrams (terminal text and SVG).

A rung's instructions become a tree: the accumulator is a series/parallel expression of
contacts hanging from a *junction* (the left rail, or the point where an earlier output or
an MPS branched off); outputs (coils, operation blocks, jumps, short-form block inputs)
attach to junctions. An OR after an output is a *merge*: the wire from the junction and
the ORed logic, coming from the rail underneath, meet at a new junction, so each contact
is drawn once (power flows left to right, as in any PLC ladder). BLK ... END_BLK is one
box with the block's pins in TwidoSuite's order: each input's network on the left, what
each output feeds on the right. The tree is laid out on a grid of cells (one element per
cell, vertical links on the boundaries between columns; a box takes one cell per row), and
the grid is drawn as text or SVG.

Live view: give `Live` (memory reader, the debug build's accumulator log for the rung,
forced objects). Wires that carry power are drawn double (═), values go under each
element (a block's configuration and values inside its box), forced values are marked
`F`. Power comes from the log (the accumulator after each instruction) where the
instruction fixes it, else from the contacts' current values.
"""

from __future__ import annotations

import html
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..address import Ref
from ..compiler.values import BLOCK_KIND_PINS, BLOCK_OUTPUTS
from ..il import ast as A
from ..il.printer import format_expr, format_instruction, format_statement

CONTACT = {"": "┤ ├", "N": "┤/├", "R": "┤P├", "F": "┤N├"}
COIL = {"ST": "( )", "STN": "(/)", "S": "(S)", "R": "(R)"}
ASCII = str.maketrans("─═│║┤├┬┴┼┌┐└┘╠╣╦╩╬╔╗╚╝", "-=|#||+++++++" "+++++++++")


# ---- the rung as a tree ----------------------------------------------------------------------
@dataclass
class Elem:
    """One drawn element: a contact, coil, box..."""

    kind: str  # contact | compare | coil | box | pin (a block input, drawn on the block) | block
    symbol: str  # "┤ ├", "( )", or a box's text
    label: str = ""  # above the element (its address)
    k: int = -1  # instruction index in the rung
    instr: A.Instruction | None = None
    ref: Ref | None = None  # the object whose value is shown
    op: str = ""  # LD AND OR XOR (contacts), for exact states from the log


@dataclass
class Leaf:
    elem: Elem
    k_out: int | None = None  # the accumulator after this instruction = power out


@dataclass
class Ser:
    items: list[Any]
    k_out: int | None = None


@dataclass
class Par:
    items: list[Any]
    k_out: int | None = None


@dataclass
class Junction:
    path: Any = None  # expression from the rail to here (None: the rail)
    children: list[Any] = field(default_factory=list)  # Elem (an output), Branch, Merge, Block
    merge: Merge | None = None  # the Merge this junction is the meeting point of


@dataclass
class Branch:
    logic: Any
    to: Junction


@dataclass
class Merge:
    """An OR after an output: the power at a junction (through `tap`, the logic since the
    output) ORed with `join`, logic from the left rail; the two meet at `to`."""

    tap: Any  # None: straight from the junction
    join: Any
    to: Junction
    k: int  # the OR: the accumulator after it is the power at `to`


# A function block's pins (inputs on the left, outputs on the right), from the compiler's
# tables; counter outputs drawn E D F top to bottom as TwidoSuite does [unsure, from memory].
_DRAW_ORDER = {"C": ("E", "D", "F")}
BOX_PINS = {k: (pins, _DRAW_ORDER.get(k, BLOCK_OUTPUTS.get(k, ())))
            for k, pins in BLOCK_KIND_PINS.items()}


@dataclass
class Block:
    """BLK ... END_BLK drawn as one box: input networks from the rail end on the pins (Elem
    kind "pin"), each output pin feeds its own junction."""

    ref: Ref
    elem: Elem  # the box (k: the BLK instruction)
    ins: Junction = field(default_factory=Junction)
    outs: dict[str, Junction] = field(default_factory=dict)
    ks: set[int] = field(default_factory=set)  # BLK OUT_BLK END_BLK: a marker on the title


def _join(cls: type, a: Any, b: Any, k: int) -> Any:
    """a then b in series (`Ser`) or in parallel (`Par`); a run of the same kind is
    extended rather than nested (a parallel group only while it is still open)."""
    if a is None:
        out = b
    elif isinstance(a, cls) and (cls is Ser or a.k_out is not None):
        out = cls(a.items + [b])
    else:
        out = cls([a, b])
    out.k_out = k
    return out


def _ser(a: Any, b: Any, k: int) -> Any:
    return _join(Ser, a, b, k)


def _par(a: Any, b: Any, k: int) -> Any:
    return _join(Par, a, b, k)


def _full(j: Junction, pend: Any, k: int) -> Any:
    if j.path is None:
        return pend
    return j.path if pend is None else _ser(j.path, pend, k)


def _operand_elem(op: A.BoolOperand | None, mod: str, k: int, instr: A.Instruction,
                  blk: Ref | None, kind_op: str) -> Elem:
    if isinstance(op, A.Compare):
        neg = "NOT " if mod == "N" else ""
        return Elem("compare", f"[{neg}{format_expr(op.left)} {op.op} "
                    f"{format_expr(op.right)}]", "", k, instr, None, kind_op)
    if isinstance(op, A.Operand):
        return Elem("contact", CONTACT.get(mod, "┤ ├"), str(op.ref), k, instr, op.ref, kind_op)
    if isinstance(op, A.BlockOutput):
        ref = Ref(blk.kind, blk.index, field=op.name) if blk is not None else None
        return Elem("contact", CONTACT.get(mod, "┤ ├"), str(ref) if ref else op.name, k, instr,
                    ref, kind_op)
    value = op.value if isinstance(op, A.Const) else 0
    return Elem("contact", "───" if value else "┤ ├", str(value), k, instr, None, kind_op)


def _output_elem(instr: A.Instruction, k: int, blk: Ref | None) -> Elem | None:
    if isinstance(instr, A.Store):
        return Elem("coil", COIL[instr.op], str(instr.target), k, instr, instr.target)
    if isinstance(instr, A.OpBlock):
        st = instr.stmt
        return Elem("box", format_statement(st), "", k, instr, getattr(st, "target", None))
    if isinstance(instr, A.Jump):
        return Elem("box", f">>%L{instr.label}", instr.op, k, instr)
    if isinstance(instr, A.SRCall):
        return Elem("box", f"[SR{instr.number}]", "", k, instr)
    if isinstance(instr, (A.Return, A.End)):
        return Elem("box", f"<{instr.op}>", "", k, instr)
    if isinstance(instr, A.Pin):
        if instr.block is None and blk is not None:  # inside BLK: a pin of the box
            return Elem("pin", instr.name, "", k, instr)
        b = instr.block or blk
        return Elem("box", f"[{b} {instr.name}]", "", k, instr,
                    Ref(b.kind, b.index) if b is not None else None)
    if isinstance(instr, A.Grafcet) and instr.op in ("#", "#D"):
        return Elem("box", f"[{format_instruction(instr)}]", "", k, instr)
    return None


def _block_output(ins: A.BoolInstr, blk: Ref) -> str | None:
    """The output pin a plain `LD Q` (or `LD %C0.D`) after OUT_BLK reads, else None."""
    op = ins.operand
    if ins.modifier:
        return None  # LDN Q and the like: a contact from the rail
    if isinstance(op, A.BlockOutput):
        return op.name
    if (isinstance(op, A.Operand) and op.ref.kind == blk.kind and op.ref.index == blk.index
            and op.ref.field in BOX_PINS.get(blk.kind, ((), ()))[1]):
        return op.ref.field
    return None


def _has_merge(j: Junction) -> bool:
    return any(isinstance(ch, Merge) or (isinstance(ch, Branch) and _has_merge(ch.to))
               for ch in j.children)


def build(rung: A.Rung, merge: bool = True) -> Junction:
    """The rung as a tree of junctions (see the module docstring). `merge=False` draws an OR
    after an output by drawing the logic before it again (the fallback when a merge would
    cross other wires)."""
    root = Junction()
    rail = root  # where a load starts (inside BLK ... OUT_BLK: the block's input side)
    cur, pend = root, None  # the accumulator = power at `cur`, then through `pend`
    mps: list[Junction] = []
    parens: list[tuple[str, str, Junction, Any]] = []
    blk: Ref | None = None
    block: Block | None = None

    def attach() -> Junction:
        nonlocal cur, pend
        if pend is not None:
            j = Junction(_full(cur, pend, pend.k_out if pend.k_out is not None else -1))
            cur.children.append(Branch(pend, j))
            cur, pend = j, None
        return cur

    def combine(op: str, e: Any, k: int) -> None:
        nonlocal cur, pend
        if op == "AND":
            pend = _ser(pend, e, k)
        elif op == "OR":
            if cur.path is not None:  # OR after an output (or an MPS)
                if pend is None and cur.merge is not None and not cur.children:
                    cur.merge.join = _par(cur.merge.join, e, k)  # OR c / OR d: c // d
                    cur.merge.k = k
                    cur.path = _par(cur.path, e, k)
                    return
                at_pin = block is not None and any(cur is j for j in block.outs.values())
                if merge and not (at_pin and not cur.children):  # LD Q / OR c: Q // c
                    m = Junction(_par(_full(cur, pend, k), e, k))
                    m.merge = Merge(pend, e, m, k)
                    cur.children.append(m.merge)
                    cur, pend = m, None
                    return
                pend, cur = _full(cur, pend, k), rail  # draw the logic again from the rail
            pend = _par(pend, e, k)
        else:  # XOR: drawn as a series box
            pend = _ser(pend, Leaf(Elem("box", "[XOR]", "", k, None)), k)
            pend = _ser(pend, e, k)

    for k, ins in enumerate(rung.instructions):
        if isinstance(ins, A.BoolInstr):
            # an OR operand's own state is not the accumulator after it
            e = Leaf(_operand_elem(ins.operand, ins.modifier, k, ins, blk, ins.op),
                     None if ins.op == "OR" else k)
            pin = (_block_output(ins, blk) if block is not None and rail is root
                   and ins.op == "LD" else None)
            if pin is not None:
                j = block.outs.setdefault(pin, Junction(e))
                cur, pend = j, None
            elif ins.op == "LD":
                cur, pend = rail, e
            else:
                combine(ins.op, e, k)
        elif isinstance(ins, A.ParenOpen):
            parens.append((ins.op, ins.modifier, cur, pend))
            cur, pend = Junction(), Leaf(_operand_elem(ins.operand, ins.modifier, k, ins, blk,
                                                       "LD"), k)
        elif isinstance(ins, A.ParenClose):
            if not parens:
                continue
            op, mod, cur, outer = parens.pop()
            inner, pend = pend, outer
            if inner is not None:
                inner.k_out = None  # the inner accumulator is not the power out
                combine(op, inner, k)
        elif isinstance(ins, A.Negate):
            pend = _ser(pend, Leaf(Elem("box", "[NOT]", "", k, ins), k), k)
        elif isinstance(ins, A.Stack):
            if ins.op == "MPS":
                mps.append(attach())
            elif mps:
                cur, pend = (mps[-1] if ins.op == "MRD" else mps.pop()), None
        elif isinstance(ins, A.Blk):
            if pend is not None:
                attach()
            blk = ins.block
            block = Block(blk, Elem("block", str(blk), "", k, ins, Ref(blk.kind, blk.index)))
            block.ks.add(k)
            root.children.append(block)
            rail = cur = block.ins
            pend = None
        elif isinstance(ins, (A.OutBlk, A.EndBlk)):
            if block is not None:
                block.ks.add(k)
                if isinstance(ins, A.EndBlk):
                    _close_block(block, root, merge)
                    blk = block = None
            rail = cur = root
            pend = None
        else:
            el = _output_elem(ins, k, blk)
            if el is None:
                continue
            unconditional = (isinstance(ins, (A.Jump, A.Return, A.End)) and
                             ins.op in ("JMP", "RET", "END"))
            if unconditional or (pend is None and cur is rail):
                rail.children.append(el)
            else:
                attach().children.append(el)
    if block is not None:
        _close_block(block, root, merge)
    if pend is not None:  # logic with no output (an unfinished rung)
        attach()
    return root


def _close_block(block: Block, root: Junction, merge: bool) -> None:
    """Output networks that OR in logic from the rail are drawn from the rail below the box,
    starting with the output's contact (%C0.D), so the rail logic does not cross the box."""
    for name, j in list(block.outs.items()):
        if not j.children:
            del block.outs[name]
        elif merge and _has_merge(j):
            del block.outs[name]
            root.children.append(Branch(j.path, j))


# ---- layout ------------------------------------------------------------------------------------
@dataclass
class BoxRow:
    """One row of a function block's box: the pins on its two sides."""

    first: bool
    last: bool
    left: str = ""  # input pin
    left_wired: bool = False
    right: str = ""  # output pin
    right_wired: bool = False
    info: str = ""  # live values, on the row's value line
    marked: str = ""  # the next instruction is: "title" BLK/OUT_BLK/END_BLK, "left", "right"


@dataclass
class Cell:
    elem: Elem | None  # None: a plain wire
    p_in: bool = False
    p_out: bool = False
    value: str = ""  # under the element (live view)
    box: BoxRow | None = None  # a row of a function block's box


@dataclass
class Grid:
    cells: dict[tuple[int, int], Cell] = field(default_factory=dict)
    vlinks: list[tuple[int, int, int, bool]] = field(default_factory=list)  # col, r1, r2, on
    rows: int = 0
    cols: int = 0
    outcol: int = 0


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
        if ref.is_block:
            return block_summary(v)
        s = str(int(v)) if isinstance(v, bool) else (f"{v:g}" if isinstance(v, float)
                                                      else str(v))
        return s + ("F" if str(ref) in self.forced else "")

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
            r = {"=": a == b, "<>": a != b, ">": a > b, ">=": a >= b, "<": a < b,
                 "<=": a <= b}[op.op]
            return (not r) if mod == "N" else r
        if el.ref is not None and mod in ("", "N"):
            try:
                v = bool(self.read(el.ref))
            except Exception:
                return None
            return v != (mod == "N")
        return None


def block_summary(b: Any) -> str:
    """A function block's fields in one short string."""
    parts = []
    for f in ("Q", "V", "P", "D", "E", "F", "S", "W"):
        if hasattr(b, f) and not callable(getattr(b, f)):
            parts.append(f"{f}={int(getattr(b, f))}")
    return " ".join(parts)


def _measure(e: Any) -> tuple[int, int]:
    """Width and height of an expression, as `_Layout.expr` places it."""
    if isinstance(e, Leaf):
        return 1, 1
    sizes = [_measure(it) for it in e.items]
    if isinstance(e, Ser):
        return sum(w for w, _ in sizes), max(h for _, h in sizes)
    return max(w for w, _ in sizes), sum(h for _, h in sizes)


def _pins_in(ch: Any) -> list[str]:
    if isinstance(ch, Elem):
        return [ch.symbol] if ch.kind == "pin" else []
    if isinstance(ch, (Branch, Merge)):
        return [n for c in ch.to.children for n in _pins_in(c)]
    return []


def _box_info(b: Any) -> list[str]:
    """A block's configuration and values for the inside of its box (live view)."""
    out = []
    if hasattr(b, "type") and hasattr(b, "base"):
        out.append(f"{b.type} {b.base}")
    vals = [f"{f}={int(getattr(b, f))}" for f in ("P", "V", "S", "W")
            if hasattr(b, f) and not callable(getattr(b, f))]
    out += [" ".join(vals[i:i + 2]) for i in range(0, len(vals), 2)]
    return out


BlockReader = Callable[[Ref], Any]
"""A configured function block by reference (None if not configured): the static view of
`softplc ladder --config`."""


def _config_info(b: Any) -> list[str]:
    """A block's configuration (no live values) for the inside of its box."""
    if b is None:
        return []
    out = []
    kind = getattr(b, "type", None)
    if kind is not None:
        out.append(f"{kind} {b.base}" if hasattr(b, "base") else str(kind))
    if isinstance(getattr(b, "P", None), int):
        out.append(f"P={b.P}")
    if isinstance(getattr(b, "steps", None), list):
        out.append(f"{len(b.steps)} steps")
    return out


class _Layout:
    def __init__(self, live: Live | None, marker: int | None = None,
                 blocks: BlockReader | None = None):
        self.g = Grid()
        self.live = live
        self.blocks = blocks
        self.marker = marker
        self.outs: list[tuple[int, int, Elem, bool]] = []
        self.pins: list[tuple[int, int, Elem, bool]] | None = None  # inside a block's inputs
        # merges to check for crossings: join row, merge column, the join's own vlinks, the
        # first row under the tap
        self.joins: list[tuple[int, int, set[int], int]] = []

    def put(self, r: int, c: int, cell: Cell) -> None:
        self.g.cells[(r, c)] = cell
        self.g.rows = max(self.g.rows, r + 1)
        self.g.cols = max(self.g.cols, c + 1)

    def override(self, node: Any, p_in: bool, p: bool) -> bool:
        if self.live is not None and node.k_out is not None:
            acc = self.live.acc(node.k_out)
            if acc is not None:
                return p_in and acc
        return p

    def expr(self, e: Any, r: int, c: int, p_in: bool) -> tuple[int, int, bool]:
        """Place an expression at (r, c); (width, height, power out)."""
        if isinstance(e, Leaf):
            el = e.elem
            closed = self.live.closed(el) if self.live and el.kind != "box" else True
            p = self.override(e, p_in, p_in and bool(closed))
            value = ""
            if self.live:
                ins = el.instr
                if el.kind == "compare" and isinstance(getattr(ins, "operand", None), A.Compare):
                    cmp_ = ins.operand
                    value = (f"{self.live.expr_text(cmp_.left)} {cmp_.op} "
                             f"{self.live.expr_text(cmp_.right)}")
                else:
                    value = self.live.value(el.ref)
            self.put(r, c, Cell(el, p_in, p, value))
            return 1, 1, p
        if isinstance(e, Ser):
            w, h, p = 0, 1, p_in
            for it in e.items:
                wi, hi, p = self.expr(it, r, c + w, p)
                w, h = w + wi, max(h, hi)
            return w, h, self.override(e, p_in, p)
        if isinstance(e, Par):
            placed = []
            h = 0
            for it in e.items:
                wi, hi, pi = self.expr(it, r + h, c, p_in)
                placed.append((r + h, wi, pi))
                h += hi
            w = max(wi for _, wi, _ in placed)
            p = any(pi for _, _, pi in placed)
            for row, wi, pi in placed:
                for cc in range(c + wi, c + w):
                    self.put(row, cc, Cell(None, pi, pi))
            last = placed[-1][0]
            self.g.vlinks.append((c, r, last, p_in))
            p = self.override(e, p_in, p)
            self.g.vlinks.append((c + w, r, last, p))
            return w, h, p
        raise TypeError(e)

    def junction(self, j: Junction, r: int, c: int, p_in: bool) -> int:
        """Place a junction's children from (r, c); returns the height."""
        h, starts = 0, []
        for ch in j.children:
            starts.append(r + h)
            h += self.child(ch, j, r + h, c, p_in)
        if len(starts) > 1:  # the link reaches the last child's first row
            self.g.vlinks.append((c, r, starts[-1], p_in))
        return max(h, 1)

    def child(self, ch: Any, j: Junction, row: int, c: int, p_in: bool) -> int:
        if isinstance(ch, Elem):
            p = p_in
            if self.live is not None and ch.k >= 0 and j.path is not None:
                acc = self.live.acc(ch.k)
                p = acc if acc is not None else p_in
            (self.pins if ch.kind == "pin" and self.pins is not None else self.outs).append(
                (row, c, ch, p))
            return 1
        if isinstance(ch, Block):
            return self.block(ch, row, c)
        if isinstance(ch, Merge):
            return self.merge(ch, row, c, p_in)
        w, hl, p = self.expr(ch.logic, row, c, p_in)
        hj = self.junction(ch.to, row, c + w, p) if ch.to.children else 1
        return max(hl, hj)

    def free_row(self, start: int, height: int, cols: int) -> int:
        """The first row from `start` where `height` rows are free left of column `cols`
        (no element, no vertical link a wire there would touch)."""
        r = start
        while True:
            rows = range(r, r + height)
            if not any((x, cc) in self.g.cells for x in rows for cc in range(cols)) and \
                    not any(1 <= b < cols and r1 <= x <= r2 for b, r1, r2, _ in self.g.vlinks
                            for x in rows):
                return r
            r += 1

    def merge(self, m: Merge, row: int, c: int, p_in: bool) -> int:
        """An OR after an output: the tap goes right from the junction, the rail logic comes
        in from below, both meet at one column; what follows the OR starts there."""
        wt, ht, pt = self.expr(m.tap, row, c, p_in) if m.tap is not None else (0, 1, p_in)
        we, he = _measure(m.join)
        cm = max(c + max(wt, 1), we)
        for cc in range(c + wt, cm):
            self.put(row, cc, Cell(None, pt, pt))
        r_e = self.free_row(row + 1, he, cm)
        nv = len(self.g.vlinks)
        _, _, pj = self.expr(m.join, r_e, 0, True)
        own = set(range(nv, len(self.g.vlinks)))
        for cc in range(we, cm):
            self.put(r_e, cc, Cell(None, pj, pj))
        pm = pt or pj
        if self.live is not None:
            acc = self.live.acc(m.k)
            pm = acc if acc is not None else pm
        self.g.vlinks.append((cm, row, r_e, pm))
        self.joins.append((r_e, cm, own, row + ht))
        hm = self.junction(m.to, row, cm, pm) if m.to.children else 1
        return max(ht, hm, r_e + he - row)

    def crossed(self) -> bool:
        """Whether a merge's rail logic crosses a vertical link, or its vertical link a
        wire: then the drawing would connect what the IL does not."""
        for r_e, cm, own, below_tap in self.joins:
            if any(i not in own and 1 <= b < cm and r1 <= r_e <= r2
                   for i, (b, r1, r2, _) in enumerate(self.g.vlinks)):
                return True
            if any((x, cm - 1) in self.g.cells for x in range(below_tap, r_e)):
                return True
        return False

    def block(self, b: Block, r: int, c0: int) -> int:
        """A function block: its input networks, the box, what its outputs feed."""
        in_names, out_names = BOX_PINS.get(b.ref.kind, ((), ()))
        order = {n: i for i, n in enumerate(in_names)}
        wired = {n for ch in b.ins.children for n in _pins_in(ch)}
        items: list[tuple[int, Any]] = [
            (min((order.get(n, len(order)) for n in _pins_in(ch)), default=len(order)), ch)
            for ch in b.ins.children]
        items += [(order[n], n) for n in in_names if n not in wired]
        items.sort(key=lambda t: t[0])
        # the input side
        left: dict[int, tuple[str, bool, bool, int]] = {}  # row -> pin, wired, power, k
        before, nv = set(self.g.cells), len(self.g.vlinks)
        self.pins, row = [], r
        for _key, it in items:
            if isinstance(it, str):
                left[row] = (it, False, False, -1)
                row += 1
            else:
                row += self.child(it, b.ins, row, c0, True)
        pins, self.pins = self.pins, None
        h_in = row - r
        cb = max([c for _, c, _, _ in pins] + [cc + 1 for (_, cc) in self.g.cells.keys() - before]
                 + [v[0] + 1 for v in self.g.vlinks[nv:]] + [c0])
        for x, c, el, p in pins:
            for cc in range(c, cb):
                self.put(x, cc, Cell(None, p, p))
            left[x] = (el.symbol, True, p, el.k)
        # the output side
        right: dict[int, tuple[str, bool, bool, int]] = {}  # row -> pin, wired, power, k
        row = r
        for n in list(out_names) + [n for n in b.outs if n not in out_names]:
            j = b.outs.get(n)
            p = True
            if self.live is not None:
                try:
                    p = bool(self.live.read(Ref(b.ref.kind, b.ref.index, field=n)))
                except Exception:  # an unconfigured block: no power shown
                    p = False
            k = j.path.elem.k if j is not None and isinstance(j.path, Leaf) else -1
            right[row] = (n, j is not None, p, k)
            row += self.junction(j, row, cb + 1, p) if j is not None else 1
        info: list[str] = []
        if self.live is not None:
            try:
                info = _box_info(self.live.read(b.elem.ref))
            except Exception:
                info = []
        elif self.blocks is not None:
            info = _config_info(self.blocks(b.elem.ref))
        height = max(h_in, row - r, len(info), 1)
        for i in range(height):
            ln, lw, lp, lk = left.get(r + i, ("", False, False, -1))
            rn, rw, rp, rk = right.get(r + i, ("", False, False, -1))
            marked = ("title" if i == 0 and self.marker in b.ks else
                      "left" if self.marker is not None and lk == self.marker else
                      "right" if self.marker is not None and rk == self.marker else "")
            self.put(r + i, cb, Cell(b.elem, lp, rp, "", BoxRow(
                i == 0, i == height - 1, ln, lw, rn, rw, info[i] if i < len(info) else "",
                marked)))
        return height

    def finish(self) -> Grid:
        g = self.g
        g.outcol = max([c for _, c, _, _ in self.outs] + [g.cols])
        for row, c, el, p in self.outs:
            for cc in range(c, g.outcol):
                self.put(row, cc, Cell(None, p, p))
            value = self.live.value(el.ref) if self.live else ""
            self.put(row, g.outcol, Cell(el, p, p, value))
        return g


def layout(rung: A.Rung, live: Live | None = None, marker: int | None = None,
           blocks: BlockReader | None = None) -> Grid:
    """The rung on a grid. An OR after an output is drawn once, its rail logic coming up
    from below; where that would cross other wires, the junction's merges are drawn after
    its other outputs, and failing that the logic before the OR is drawn again."""
    for tree in (build(rung), _merges_last(build(rung)), build(rung, merge=False)):
        lay = _Layout(live, marker, blocks)
        lay.junction(tree, 0, 0, True)
        if not lay.crossed():
            break
    return lay.finish()


def _merges_last(j: Junction) -> Junction:
    """The tree with each junction's merges after its other children."""
    j.children.sort(key=lambda ch: isinstance(ch, Merge))
    for ch in j.children:
        if isinstance(ch, (Branch, Merge)):
            _merges_last(ch.to)
        elif isinstance(ch, Block):
            _merges_last(ch.ins)
            for o in ch.outs.values():
                _merges_last(o)
    return j


# ---- text ---------------------------------------------------------------------------------------
_GLYPH = {  # (up, down, left, right) -> box-drawing character
    (0, 0, 1, 1): "─", (0, 0, 1, 0): "─", (0, 0, 0, 1): "─", (1, 1, 0, 0): "│",
    (1, 0, 0, 0): "│", (0, 1, 0, 0): "│", (0, 1, 0, 1): "┌", (0, 1, 1, 0): "┐",
    (1, 0, 0, 1): "└", (1, 0, 1, 0): "┘", (1, 1, 0, 1): "├", (1, 1, 1, 0): "┤",
    (0, 1, 1, 1): "┬", (1, 0, 1, 1): "┴", (1, 1, 1, 1): "┼", (0, 0, 0, 0): " ",
}
_HEAVY = str.maketrans("─│┌┐└┘├┤┬┴┼", "═║╔╗╚╝╠╣╦╩╬")


def _wire(on: bool) -> str:
    return "═" if on else "─"


def _center(s: str, w: int, fill: str = " ") -> str:
    left = (w - len(s)) // 2
    return fill * left + s + fill * (w - len(s) - left)


def _box_inner(cell: Cell) -> int:
    """Characters inside a box row (between its two sides)."""
    b = cell.box
    assert b is not None and cell.elem is not None
    return max(len(cell.elem.symbol) + 3, len(b.left) + len(b.right) + 3, len(b.info))


def _box_lines(cell: Cell, w: int, pw: bool) -> list[str]:
    """A box row in a cell `w` wide: label (top border), wire, value and bottom lines."""
    b = cell.box
    assert b is not None and cell.elem is not None
    iw = w - 4
    title = (">" if b.marked == "title" else "") + cell.elem.symbol
    left = (">" if b.marked == "left" else "") + b.left
    right = (">" if b.marked == "right" else "") + b.right
    top = (" ┌" + _center(title, iw, "─") + "┐ ") if b.first else " │" + " " * iw + "│ "
    wire = ((_wire(cell.p_in and pw) + "┤") if b.left_wired else " │") + left + \
        " " * (iw - len(left) - len(right)) + right + \
        (("├" + _wire(cell.p_out and pw)) if b.right_wired else "│ ")
    bottom = (" └" + "─" * iw + "┘ ") if b.last else " │" + " " * iw + "│ "
    return [top, wire, " │" + _center(b.info, iw) + "│ ", bottom]


def _joins(cell: Cell | None, side: str) -> bool:
    """Whether a cell has a wire on that side (a box only where a pin is wired)."""
    if cell is None:
        return False
    if cell.box is not None:
        return cell.box.left_wired if side == "left" else cell.box.right_wired
    return True


def render_text(rung: A.Rung, live: Live | None = None, *, ascii: bool = False,
                header: bool = True, marker: int | None = None,
                blocks: BlockReader | None = None) -> str:
    """The rung as terminal text. `marker`: instruction index of the next instruction to
    run (drawn `>` before its element); `blocks`: show each box's configuration."""
    g = layout(rung, live, marker, blocks)
    out: list[str] = []
    if header:
        where = f" SR{rung.subroutine}" if rung.subroutine is not None else ""
        lbl = f" %L{rung.label}:" if rung.label is not None else ""
        out.append(f"rung {rung.index}{where}{lbl}" + (f"  {rung.title}" if rung.title else ""))
    if not g.cells:
        out.append("  (no logic)" if not rung.instructions else
                   "  " + "; ".join(format_instruction(i) for i in rung.instructions))
        return "\n".join(out) + "\n"
    ncols = g.outcol + 1
    width = [3] * ncols
    for (_, c), cell in g.cells.items():
        el = cell.elem
        if cell.box is not None:
            width[c] = max(width[c], _box_inner(cell) + 2)
        elif el is not None:
            width[c] = max(width[c], len(el.symbol), len(el.label) + (1 if marker is not None
                                                                       else 0), len(cell.value))
    width = [w + 2 for w in width]
    vert: dict[tuple[int, int], tuple[bool, bool, bool]] = {}  # (row, col) -> up, down, on
    for col, r1, r2, on in g.vlinks:
        for r in range(r1, r2 + 1):
            up, down, o = vert.get((r, col), (False, False, False))
            vert[(r, col)] = (up or r > r1, down or r < r2, o or on)
    pw = live is not None  # power is drawn only in the live view
    for r in range(g.rows):
        # label, wire, value (live view), the bottom of a box that ends on this row
        rows: list[list[str]] = [[], [], [], []]
        rail_right = _joins(g.cells.get((r, 0)), "left")
        rows[0].append("│")
        rows[1].append("├" if rail_right else "│")
        rows[2].append("│")
        rows[3].append("│")
        for c in range(ncols + 1):
            # the boundary before column c (the left rail is boundary 0)
            if c > 0:
                up, down, on = vert.get((r, c), (False, False, False))
                left = _joins(g.cells.get((r, c - 1)), "right")
                right = c < ncols and _joins(g.cells.get((r, c)), "left")
                if c == ncols:  # the right rail
                    rows[0].append("│")
                    rows[1].append("┤" if left else "│")
                    rows[2].append("│")
                    rows[3].append("│")
                    break
                ch = _GLYPH[(int(up), int(down), int(left), int(right))]
                on = on and pw
                if on:
                    ch = ch.translate(_HEAVY)
                elif left and not (up or down):
                    ch = _wire(g.cells[(r, c - 1)].p_out and pw)
                rows[0].append("│" if up else " ")
                rows[1].append(ch)
                rows[2].append(("║" if on else "│") if down else " ")
                rows[3].append(rows[2][-1])
            w = width[c]
            cell = g.cells.get((r, c))
            if cell is None:
                for i in range(4):
                    rows[i].append(" " * w)
                continue
            if cell.box is not None:
                for i, s in enumerate(_box_lines(cell, w, pw)):
                    rows[i].append(s)
                continue
            el = cell.elem
            if el is None:
                rows[0].append(" " * w)
                rows[1].append(_wire(cell.p_out and pw) * w)
                rows[2].append(" " * w)
                rows[3].append(" " * w)
                continue
            label = el.label
            if marker is not None and el.k == marker:
                label = ">" + label
            rows[0].append(_center(label, w))
            sym = el.symbol
            if sym == "───":  # a constant 1: a plain wire
                sym = _wire(cell.p_out and pw) * 3
            left = (w - len(sym)) // 2
            rows[1].append(_wire(cell.p_in and pw) * left + sym + _wire(cell.p_out and pw) *
                           (w - len(sym) - left))
            rows[2].append(_center(cell.value, w))
            rows[3].append(" " * w)
        box_ends = any(cell.box is not None and cell.box.last
                       for (rr, _), cell in g.cells.items() if rr == r)
        box_info = any(cell.box is not None and cell.box.info
                       for (rr, _), cell in g.cells.items() if rr == r)
        for i in (0, 1, 2, 3):
            if (i == 2 and not (pw or box_info)) or (i == 3 and not box_ends):
                continue
            if i in (0, 2) and r > 0 and not "".join(rows[i]).strip(" │║"):
                continue
            out.append("".join(rows[i]).rstrip())
    text = "\n".join(out) + "\n"
    return text.translate(ASCII) if ascii else text


def render_program_text(program: A.Program, *, ascii: bool = False,
                        blocks: BlockReader | None = None) -> str:
    parts = []
    for title_sec, rungs in _sections(program):
        if title_sec:
            parts.append(f"== {title_sec} ==\n")
        for r in rungs:
            parts.append(render_text(r, ascii=ascii, blocks=blocks))
    return "\n".join(parts)


def _sections(program: A.Program) -> list[tuple[str, list[A.Rung]]]:
    out: list[tuple[str, list[A.Rung]]] = []
    key: Any = object()
    for r in program.rungs:
        k = ("SR", r.subroutine) if r.subroutine is not None else ("S", r.section)
        if k != key:
            key = k
            if r.subroutine is not None:
                title = f"SR{r.subroutine}"
            elif r.section is not None:
                t = program.section_titles.get(r.section, "")
                title = f"SECTION {r.section}" + (f": {t}" if t else "")
            else:
                title = ""
            out.append((title, []))
        out[-1][1].append(r)
    return out


# ---- SVG -----------------------------------------------------------------------------
CH, ROW_H, PAD = 7.2, 48, 20  # pixels per character, per row, margin


def render_program_svg(program: A.Program, blocks: BlockReader | None = None) -> str:
    """The whole program as one SVG document (hand-written, no dependencies)."""
    body: list[str] = []
    y = PAD
    width = 400.0
    for title_sec, rungs in _sections(program):
        if title_sec:
            body.append(_text(PAD, y + 14, title_sec, size=16, weight="bold"))
            y += 30
        for r in rungs:
            h, w = _svg_rung(r, PAD, y, body, blocks=blocks)
            y += h + 16
            width = max(width, w + PAD, PAD + (len(r.title) + 12) * CH)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{y + PAD:.0f}" '
            f'viewBox="0 0 {width:.0f} {y + PAD:.0f}" font-family="monospace" font-size="12">\n'
            f'<rect width="100%" height="100%" fill="white"/>\n' + "\n".join(body) + "\n</svg>\n")


def _text(x: float, y: float, s: str, *, size: int = 12, anchor: str = "start",
          weight: str = "normal", fill: str = "") -> str:
    colour = f' fill="{fill}"' if fill else ""
    return (f'<text x="{x:.1f}" y="{y:.1f}" font-size="{size}" text-anchor="{anchor}" '
            f'font-weight="{weight}"{colour}>{html.escape(s)}</text>')


POWER_COLOUR = "#1a9c3c"  # live view: wires and elements that carry power


def _line(x1: float, y1: float, x2: float, y2: float, on: bool = False) -> str:
    if on:
        return (f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" '
                f'stroke="{POWER_COLOUR}" stroke-width="3" class="on"/>')
    return f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" stroke="black"/>'


def render_rung_svg(rung: A.Rung, live: Live | None = None) -> str:
    """One rung as a standalone SVG document; with `live`, powered wires are drawn thick
    and green (class "on") and each element's current value is written under it."""
    body: list[str] = []
    h, w = _svg_rung(rung, PAD, PAD, body, live)
    width = max(w + PAD, PAD + (len(rung.title) + 12) * CH)
    height = h + 2 * PAD
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
            f'viewBox="0 0 {width:.0f} {height:.0f}" font-family="monospace" font-size="12">\n'
            f'<rect width="100%" height="100%" fill="white"/>\n' + "\n".join(body) + "\n</svg>\n")


def _svg_rung(rung: A.Rung, x0: float, y0: float, body: list[str],
              live: Live | None = None, blocks: BlockReader | None = None
              ) -> tuple[float, float]:
    """Draw one rung at (x0, y0); returns (height, width)."""
    title = f"rung {rung.index}" + (f" %L{rung.label}:" if rung.label is not None else "") + \
        (f"  {rung.title}" if rung.title else "")
    body.append(_text(x0, y0 + 12, title, weight="bold"))
    top = y0 + 20
    g = layout(rung, live, blocks=blocks)
    pw = live is not None  # power is drawn only in the live view
    if not g.cells:
        body.append(_text(x0 + 10, top + 16, "; ".join(format_instruction(i)
                                                      for i in rung.instructions) or "(no logic)"))
        return 40, x0 + 400
    ncols = g.outcol + 1
    widths = [3] * ncols
    for (_, c), cell in g.cells.items():
        if cell.box is not None:
            widths[c] = max(widths[c], _box_inner(cell) + 2)
        elif cell.elem is not None:
            widths[c] = max(widths[c], len(cell.elem.symbol), len(cell.elem.label))
    xs = [x0 + 10]
    for w in widths:
        xs.append(xs[-1] + (w + 4) * CH)
    height = g.rows * ROW_H

    def wy(r: int) -> float:
        return top + r * ROW_H + 28

    body.append(_line(x0 + 10, top, x0 + 10, top + height, pw))
    body.append(_line(xs[-1], top, xs[-1], top + height))
    for (r, c), cell in sorted(g.cells.items()):
        xa, xb, y = xs[c], xs[c + 1], wy(r)
        el = cell.elem
        on_in, on_out = pw and cell.p_in, pw and cell.p_out
        if el is None:
            body.append(_line(xa, y, xb, y, on_out))
            continue
        xm = (xa + xb) / 2
        if cell.box is not None:
            _svg_box_row(cell, xa + 2 * CH, xb - 2 * CH, xa, xb, y, body, pw)
            continue
        if cell.value:
            body.append(_text(xm, y + 24, cell.value, size=11, anchor="middle",
                              fill="#0b4f8a"))
        if el.kind == "contact" and el.symbol == "───":
            body.append(_line(xa, y, xb, y, on_out))
        elif el.kind == "contact":
            body += [_line(xa, y, xm - 6, y, on_in), _line(xm + 6, y, xb, y, on_out),
                     _line(xm - 6, y - 10, xm - 6, y + 10), _line(xm + 6, y - 10, xm + 6, y + 10)]
            mark = el.symbol[1].strip()
            if mark == "/":
                body.append(_line(xm - 6, y + 10, xm + 6, y - 10))
            elif mark:
                body.append(_text(xm, y + 4, mark, size=10, anchor="middle"))
        elif el.kind == "coil":
            body += [_line(xa, y, xm - 9, y, on_in), _line(xm + 9, y, xb, y, on_out),
                     f'<path d="M{xm - 5:.1f},{y - 10:.1f} A12,12 0 0 0 {xm - 5:.1f},{y + 10:.1f}" '
                     f'fill="none" stroke="black"/>',
                     f'<path d="M{xm + 5:.1f},{y - 10:.1f} A12,12 0 0 1 {xm + 5:.1f},{y + 10:.1f}" '
                     f'fill="none" stroke="black"/>']
            mark = el.symbol[1].strip()
            if mark:
                body.append(_text(xm, y + 4, mark, size=10, anchor="middle"))
        else:
            tw = len(el.symbol) * CH + 8
            body += [_line(xa, y, xm - tw / 2, y, on_in), _line(xm + tw / 2, y, xb, y, on_out),
                     f'<rect x="{xm - tw / 2:.1f}" y="{y - 10:.1f}" width="{tw:.1f}" height="20" '
                     f'fill="none" stroke="black"/>',
                     _text(xm, y + 4, el.symbol, anchor="middle")]
        if el.label:
            body.append(_text(xm, y - 14, el.label, size=11, anchor="middle"))
    for col, r1, r2, on in g.vlinks:
        body.append(_line(xs[col], wy(r1), xs[col], wy(r2), pw and on))
    return height + 24, xs[-1]


def _svg_box_row(cell: Cell, left: float, right: float, xa: float, xb: float, y: float,
                 body: list[str], pw: bool = False) -> None:
    """One row of a function block: its sides (top and title on the first row, bottom on
    the last), its pins and their wires."""
    b = cell.box
    assert b is not None and cell.elem is not None
    y1 = y - 26 if b.first else y - ROW_H + 14
    y2 = y + 14  # meets the next row's y1
    body += [_line(left, y1, left, y2), _line(right, y1, right, y2)]
    if b.first:
        body += [_line(left, y1, right, y1),
                 _text((left + right) / 2, y - 12, cell.elem.symbol, anchor="middle",
                       weight="bold")]
    if b.last:
        body.append(_line(left, y2, right, y2))
    if b.left:
        body.append(_text(left + 4, y + 4, b.left, size=11))
    if b.right:
        body.append(_text(right - 4, y + 4, b.right, size=11, anchor="end"))
    if b.info:  # live values, or the configuration (ladder --config)
        body.append(_text((left + right) / 2, y + 12, b.info, size=10, anchor="middle",
                          fill="#0b4f8a"))  # under the pins, above the box's bottom line
    if b.left_wired:
        body.append(_line(xa, y, left, y, pw and cell.p_in))
    if b.right_wired:
        body.append(_line(right, y, xb, y, pw and cell.p_out))
