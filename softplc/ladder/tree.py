"""The rung as a tree of contacts, junctions, merges, outputs and block boxes."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from softplc.compiler.values import BLOCK_KIND_PINS, BLOCK_OUTPUTS
from softplc.il import ast as A
from softplc.il import rungtree
from softplc.il.printer import format_expr, format_instruction, format_statement
from softplc.twido.address import Ref

CONTACT = {"": "┤ ├", "N": "┤/├", "R": "┤P├", "F": "┤N├"}
COIL = {"ST": "( )", "STN": "(/)", "S": "(S)", "R": "(R)"}
ASCII = str.maketrans("─═│║┤├┬┴┼┌┐└┘╠╣╦╩╬╔╗╚╝", "-=|#||+++++++" "+++++++++")


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

    @property
    def name(self) -> str:
        """The symbol drawn above a contact's or coil's address (softplc.twido.symbols)."""
        if self.ref is None or self.kind not in ("contact", "coil"):
            return ""
        return self.ref.symbol or ""


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
        ref = Ref(blk.kind, blk.index, field=op.name).with_symbol(
            f"{blk.symbol}.{op.name}" if blk.symbol else None) if blk is not None else None
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


def _contact(st: rungtree.Step) -> Elem:
    """The contact or comparison of a LD/AND/OR/XOR or of an opening `AND(` (drawn as a
    load: its operand starts the logic inside the parentheses)."""
    ins = st.instr
    assert isinstance(ins, (A.BoolInstr, A.ParenOpen))
    return _operand_elem(ins.operand, ins.modifier, st.k, ins, st.block,
                         ins.op if isinstance(ins, A.BoolInstr) else "LD")


def element(st: rungtree.Step) -> Elem | None:
    """The element an instruction draws (contact, comparison, coil, box), None for one
    that only shapes the rung (a closing parenthesis, MPS, the block markers...)."""
    if isinstance(st.instr, (A.BoolInstr, A.ParenOpen)):
        return _contact(st)
    return _output_elem(st.instr, st.k, st.block)


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


def short_form_block(st: rungtree.Step) -> Ref | None:
    """The block of a short-form input outside BLK (`IN %TM0`), drawn as its box."""
    ins = st.instr
    return ins.block if isinstance(ins, A.Pin) and st.block_k is None else None


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
    tree = rungtree.build(rung)  # what each `)`, MRD, MPP and block instruction refers to
    saved: dict[int, Any] = {}  # at each `(`: (cur, pend); at each MPS: its junction
    blocks: dict[int, Block] = {}  # by BLK instruction
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

    for st in tree.steps:
        k, ins, blk = st.k, st.instr, st.block
        block = blocks.get(st.block_k) if st.block_k is not None else None
        if isinstance(ins, (A.OutBlk, A.EndBlk)):  # (outside a block too: back to the rail)
            if block is not None:
                block.ks.add(k)
                if isinstance(ins, A.EndBlk):
                    _close_block(block, root, merge)
            rail = cur = root
            pend = None
        elif not st.ok:
            continue
        elif isinstance(ins, A.BoolInstr):
            # an OR operand's own state is not the accumulator after it
            e = Leaf(_contact(st), None if ins.op == "OR" else k)
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
            saved[k] = (cur, pend)
            cur, pend = Junction(), Leaf(_contact(st), k)
        elif isinstance(ins, A.ParenClose):
            op = tree.steps[st.opener].instr.op
            cur, outer = saved[st.opener]
            inner, pend = pend, outer
            if inner is not None:
                inner.k_out = None  # the inner accumulator is not the power out
                combine(op, inner, k)
        elif isinstance(ins, A.Negate):
            pend = _ser(pend, Leaf(Elem("box", "[NOT]", "", k, ins), k), k)
        elif isinstance(ins, A.Stack):
            if ins.op == "MPS":
                saved[k] = attach()
            elif st.opener is not None:
                cur, pend = saved[st.opener], None
        elif isinstance(ins, A.Blk):
            if pend is not None:
                attach()
            blocks[k] = block = Block(blk, Elem("block", str(blk), "", k, ins,
                                                Ref(blk.kind, blk.index)))
            block.ks.add(k)
            root.children.append(block)
            rail = cur = block.ins
            pend = None
        elif short_form_block(st) is not None:
            # the short form `IN %TM0`: the block's box with that one input wired, as the
            # BLK form draws it (TwidoSuite draws the timer, not an operation box)
            b = short_form_block(st)
            assert b is not None and isinstance(ins, A.Pin)
            box = Block(b, Elem("block", str(b), "", k, ins, Ref(b.kind, b.index)))
            box.ks.add(k)
            box.ins.children.append(Elem("pin", ins.name, "", k, ins))
            (rail if pend is None and cur is rail else attach()).children.append(box)
        else:
            el = element(st)
            if el is None:
                continue
            unconditional = (isinstance(ins, (A.Jump, A.Return, A.End)) and
                             ins.op in ("JMP", "RET", "END"))
            if unconditional or (pend is None and cur is rail):
                rail.children.append(el)
            else:
                attach().children.append(el)
    if tree.open_block is not None:
        _close_block(blocks[tree.open_block], root, merge)
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
