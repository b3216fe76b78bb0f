"""The tree laid out on a grid of cells (one element per cell, a box one cell per row)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from softplc.il import ast as A
from softplc.ladder.live import Live
from softplc.ladder.tree import (
    BOX_PINS,
    Block,
    Branch,
    Elem,
    Junction,
    Leaf,
    Merge,
    Par,
    Ser,
    build,
)
from softplc.twido.address import Ref


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
            return self.block(ch, row, c, p_in)
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

    def block(self, b: Block, r: int, c0: int, p_in: bool = True) -> int:
        """A function block: its input networks, the box, what its outputs feed. `p_in`:
        the power where it hangs (the rail for BLK; the logic before a short-form pin)."""
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
                row += self.child(it, b.ins, row, c0, p_in)
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
