"""Instruction List rungs drawn as ladder diagrams (terminal text and SVG).

A rung's instructions become a tree: the accumulator is a series/parallel expression of
contacts hanging from a *junction* (the left rail, or the point where an earlier output or
an MPS branched off); outputs (coils, operation blocks, jumps, block inputs) attach to
junctions. The tree is laid out on a grid of cells (one element per cell, vertical links
on the boundaries between columns), and the grid is drawn as text or SVG.

Live view: give `Live` (memory reader, the debug build's accumulator log for the rung,
forced objects). Wires that carry power are drawn double (═), values go under each
element, forced values are marked `F`. Power comes from the log (the accumulator after
each instruction) where the instruction fixes it, else from the contacts' current values.
"""

from __future__ import annotations

import html
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..address import Ref
from ..il import ast as A
from ..il.printer import format_expr, format_instruction, format_statement

CONTACT = {"": "┤ ├", "N": "┤/├", "R": "┤P├", "F": "┤N├"}
COIL = {"ST": "( )", "STN": "(/)", "S": "(S)", "R": "(R)"}
ASCII = str.maketrans("─═│║┤├┬┴┼┌┐└┘╠╣╦╩╬╔╗╚╝", "-=|#||+++++++" "+++++++++")


# ---- the rung as a tree ----------------------------------------------------------------------
@dataclass
class Elem:
    """One drawn element: a contact, coil, box..."""

    kind: str  # contact | compare | coil | box | text
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
    children: list[Any] = field(default_factory=list)  # Elem (an output) or Branch


@dataclass
class Branch:
    logic: Any
    to: Junction


def _ser(a: Any, b: Any, k: int) -> Any:
    if a is None:
        out = b
    elif isinstance(a, Ser):
        out = Ser(a.items + [b])
    else:
        out = Ser([a, b])
    out.k_out = k
    return out


def _par(a: Any, b: Any, k: int) -> Any:
    if a is None:
        out = b
    elif isinstance(a, Par) and a.k_out is not None:
        out = Par(a.items + [b])
    else:
        out = Par([a, b])
    out.k_out = k
    return out


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
        return Elem("box", format_statement(st), "", k, instr, st.target)
    if isinstance(instr, A.Jump):
        return Elem("box", f">>%L{instr.label}", instr.op, k, instr)
    if isinstance(instr, A.SRCall):
        return Elem("box", f"[SR{instr.number}]", "", k, instr)
    if isinstance(instr, (A.Return, A.End)):
        return Elem("box", f"<{instr.op}>", "", k, instr)
    if isinstance(instr, A.Pin):
        b = instr.block or blk
        return Elem("box", f"[{b} {instr.name}]", "", k, instr,
                    Ref(b.kind, b.index) if b is not None else None)
    if isinstance(instr, A.Grafcet) and instr.op in ("#", "#D"):
        return Elem("box", f"[{format_instruction(instr)}]", "", k, instr)
    return None


def build(rung: A.Rung) -> Junction:
    """The rung as a tree of junctions (see the module docstring)."""
    root = Junction()
    cur, pend = root, None  # the accumulator = power at `cur`, then through `pend`
    mps: list[Junction] = []
    parens: list[tuple[str, str, Junction, Any]] = []
    blk: Ref | None = None

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
            if cur is not root and cur.path is not None:  # OR after an output: redraw the path
                pend, cur = _full(cur, pend, k), root
            pend = _par(pend, e, k)
        else:  # XOR: drawn as a series box
            pend = _ser(pend, Leaf(Elem("box", "[XOR]", "", k, None)), k)
            pend = _ser(pend, e, k)

    for k, ins in enumerate(rung.instructions):
        if isinstance(ins, A.BoolInstr):
            e = Leaf(_operand_elem(ins.operand, ins.modifier, k, ins, blk, ins.op), k)
            if ins.op == "LD":
                cur, pend = root, e
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
            blk = ins.block
        elif isinstance(ins, A.EndBlk):
            blk = None
        else:
            el = _output_elem(ins, k, blk)
            if el is None:
                continue
            unconditional = (isinstance(ins, (A.Jump, A.Return, A.End)) and
                             ins.op in ("JMP", "RET", "END"))
            if unconditional or (pend is None and cur is root):
                root.children.append(el)
            else:
                attach().children.append(el)
    if pend is not None:  # logic with no output (an unfinished rung)
        attach()
    return root


# ---- layout ------------------------------------------------------------------------------------
@dataclass
class Cell:
    elem: Elem | None  # None: a plain wire
    p_in: bool = False
    p_out: bool = False
    value: str = ""  # under the element (live view)


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
        if el.op == "LD" or isinstance(ins, A.ParenOpen):
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


class _Layout:
    def __init__(self, live: Live | None):
        self.g = Grid()
        self.live = live
        self.outs: list[tuple[int, int, Elem, bool]] = []

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
            row = r + h
            starts.append(row)
            if isinstance(ch, Elem):
                p = p_in
                if self.live is not None and ch.k >= 0 and j.path is not None:
                    acc = self.live.acc(ch.k)
                    p = acc if acc is not None else p_in
                self.outs.append((row, c, ch, p))
                h += 1
            else:
                w, hl, p = self.expr(ch.logic, row, c, p_in)
                hj = self.junction(ch.to, row, c + w, p) if ch.to.children else 1
                h += max(hl, hj)
        if len(starts) > 1:  # the link reaches the last child's first row
            self.g.vlinks.append((c, r, starts[-1], p_in))
        return max(h, 1)

    def finish(self) -> Grid:
        g = self.g
        g.outcol = max([c for _, c, _, _ in self.outs] + [g.cols])
        for row, c, el, p in self.outs:
            for cc in range(c, g.outcol):
                self.put(row, cc, Cell(None, p, p))
            value = self.live.value(el.ref) if self.live else ""
            self.put(row, g.outcol, Cell(el, p, p, value))
        return g


def layout(rung: A.Rung, live: Live | None = None) -> Grid:
    lay = _Layout(live)
    lay.junction(build(rung), 0, 0, True)
    return lay.finish()


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


def render_text(rung: A.Rung, live: Live | None = None, *, ascii: bool = False,
                header: bool = True, marker: int | None = None) -> str:
    """The rung as terminal text. `marker`: instruction index of the next instruction to
    run (drawn `>` before its element)."""
    g = layout(rung, live)
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
        if el is not None:
            width[c] = max(width[c], len(el.symbol), len(el.label) + (1 if marker is not None
                                                                       else 0), len(cell.value))
    width = [w + 2 for w in width]
    vert: dict[tuple[int, int], tuple[bool, bool, bool]] = {}  # (row, col) -> up, down, on
    for col, r1, r2, on in g.vlinks:
        for r in range(r1, r2 + 1):
            up, down, o = vert.get((r, col), (False, False, False))
            vert[(r, col)] = (up or r > r1, down or r < r2, o or on)
    lines_per_row = 3 if live is not None else 2
    pw = live is not None  # power is drawn only in the live view
    for r in range(g.rows):
        rows = [[], [], []]
        # the left rail
        rail_right = (r, 0) in g.cells
        rows[0].append("│")
        rows[1].append("├" if rail_right else "│")
        rows[2].append("│")
        for c in range(ncols + 1):
            # the boundary before column c (the left rail is boundary 0)
            if c > 0:
                up, down, on = vert.get((r, c), (False, False, False))
                left = (r, c - 1) in g.cells
                right = (r, c) in g.cells and c < ncols
                if c == ncols:  # the right rail
                    rows[0].append("│")
                    rows[1].append("┤" if left else "│")
                    rows[2].append("│")
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
            w = width[c]
            cell = g.cells.get((r, c))
            if cell is None:
                for i in range(3):
                    rows[i].append(" " * w)
                continue
            el = cell.elem
            if el is None:
                rows[0].append(" " * w)
                rows[1].append(_wire(cell.p_out and pw) * w)
                rows[2].append(" " * w)
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
        for i in range(lines_per_row):
            if i == 2 or i == 0:
                if not "".join(rows[i]).strip(" │║"):
                    if i == 0 and r > 0:
                        continue
            out.append("".join(rows[i]).rstrip())
    text = "\n".join(out) + "\n"
    return text.translate(ASCII) if ascii else text


def render_program_text(program: A.Program, *, ascii: bool = False) -> str:
    parts = []
    for title_sec, rungs in _sections(program):
        if title_sec:
            parts.append(f"== {title_sec} ==\n")
        for r in rungs:
            parts.append(render_text(r, ascii=ascii))
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


def render_program_svg(program: A.Program) -> str:
    """The whole program as one SVG document (hand-written, no dependencies)."""
    body: list[str] = []
    y = PAD
    width = 400.0
    for title_sec, rungs in _sections(program):
        if title_sec:
            body.append(_text(PAD, y + 14, title_sec, size=16, weight="bold"))
            y += 30
        for r in rungs:
            h, w = _svg_rung(r, PAD, y, body)
            y += h + 16
            width = max(width, w + PAD, PAD + (len(r.title) + 12) * CH)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{y + PAD:.0f}" '
            f'viewBox="0 0 {width:.0f} {y + PAD:.0f}" font-family="monospace" font-size="12">\n'
            f'<rect width="100%" height="100%" fill="white"/>\n' + "\n".join(body) + "\n</svg>\n")


def _text(x: float, y: float, s: str, *, size: int = 12, anchor: str = "start",
          weight: str = "normal") -> str:
    return (f'<text x="{x:.1f}" y="{y:.1f}" font-size="{size}" text-anchor="{anchor}" '
            f'font-weight="{weight}">{html.escape(s)}</text>')


def _line(x1: float, y1: float, x2: float, y2: float) -> str:
    return f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" stroke="black"/>'


def _svg_rung(rung: A.Rung, x0: float, y0: float, body: list[str]) -> tuple[float, float]:
    """Draw one rung at (x0, y0); returns (height, width)."""
    title = f"rung {rung.index}" + (f" %L{rung.label}:" if rung.label is not None else "") + \
        (f"  {rung.title}" if rung.title else "")
    body.append(_text(x0, y0 + 12, title, weight="bold"))
    top = y0 + 20
    g = layout(rung)
    if not g.cells:
        body.append(_text(x0 + 10, top + 16, "; ".join(format_instruction(i)
                                                      for i in rung.instructions) or "(no logic)"))
        return 40, x0 + 400
    ncols = g.outcol + 1
    widths = [3] * ncols
    for (_, c), cell in g.cells.items():
        if cell.elem is not None:
            widths[c] = max(widths[c], len(cell.elem.symbol), len(cell.elem.label))
    xs = [x0 + 10]
    for w in widths:
        xs.append(xs[-1] + (w + 4) * CH)
    height = g.rows * ROW_H

    def wy(r: int) -> float:
        return top + r * ROW_H + 28

    body.append(_line(x0 + 10, top, x0 + 10, top + height))
    body.append(_line(xs[-1], top, xs[-1], top + height))
    for (r, c), cell in sorted(g.cells.items()):
        xa, xb, y = xs[c], xs[c + 1], wy(r)
        el = cell.elem
        if el is None:
            body.append(_line(xa, y, xb, y))
            continue
        xm = (xa + xb) / 2
        if el.kind == "contact" and el.symbol != "───":
            body += [_line(xa, y, xm - 6, y), _line(xm + 6, y, xb, y),
                     _line(xm - 6, y - 10, xm - 6, y + 10), _line(xm + 6, y - 10, xm + 6, y + 10)]
            mark = el.symbol[1].strip()
            if mark == "/":
                body.append(_line(xm - 6, y + 10, xm + 6, y - 10))
            elif mark:
                body.append(_text(xm, y + 4, mark, size=10, anchor="middle"))
        elif el.kind == "coil":
            body += [_line(xa, y, xm - 9, y), _line(xm + 9, y, xb, y),
                     f'<path d="M{xm - 5:.1f},{y - 10:.1f} A12,12 0 0 0 {xm - 5:.1f},{y + 10:.1f}" '
                     f'fill="none" stroke="black"/>',
                     f'<path d="M{xm + 5:.1f},{y - 10:.1f} A12,12 0 0 1 {xm + 5:.1f},{y + 10:.1f}" '
                     f'fill="none" stroke="black"/>']
            mark = el.symbol[1].strip()
            if mark:
                body.append(_text(xm, y + 4, mark, size=10, anchor="middle"))
        else:
            tw = len(el.symbol) * CH + 8
            body += [_line(xa, y, xm - tw / 2, y), _line(xm + tw / 2, y, xb, y),
                     f'<rect x="{xm - tw / 2:.1f}" y="{y - 10:.1f}" width="{tw:.1f}" height="20" '
                     f'fill="none" stroke="black"/>',
                     _text(xm, y + 4, el.symbol, anchor="middle")]
        if el.label:
            body.append(_text(xm, y - 14, el.label, size=11, anchor="middle"))
    for col, r1, r2, _on in g.vlinks:
        body.append(_line(xs[col], wy(r1), xs[col], wy(r2)))
    for r in range(g.rows):
        if (r, 0) in g.cells:
            pass  # the rail meets the wire at x0 + 10
    return height + 24, xs[-1]
