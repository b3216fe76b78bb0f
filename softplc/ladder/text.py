"""The grid drawn as terminal text (box-drawing characters or ASCII)."""

from __future__ import annotations

from typing import Any

from softplc.il import ast as A
from softplc.il.printer import format_instruction
from softplc.ladder.layout import BlockReader, Cell, layout
from softplc.ladder.live import Live
from softplc.ladder.tree import ASCII

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


def box_inner_width(cell: Cell) -> int:
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
            width[c] = max(width[c], box_inner_width(cell) + 2)
        elif el is not None:
            width[c] = max(width[c], len(el.symbol), len(el.label) + (1 if marker is not None
                                                                       else 0), len(cell.value),
                           len(el.name))
    width = [w + 2 for w in width]
    vert: dict[tuple[int, int], tuple[bool, bool, bool]] = {}  # (row, col) -> up, down, on
    for col, r1, r2, on in g.vlinks:
        for r in range(r1, r2 + 1):
            up, down, o = vert.get((r, col), (False, False, False))
            vert[(r, col)] = (up or r > r1, down or r < r2, o or on)
    pw = live is not None  # power is drawn only in the live view
    for r in range(g.rows):
        # label, wire, value (live view), the bottom of a box that ends on this row, and
        # the symbols above the labels (rows[4], drawn first, when the row has one)
        rows: list[list[str]] = [[], [], [], [], []]
        rail_right = _joins(g.cells.get((r, 0)), "left")
        rows[0].append("│")
        rows[4].append("│")
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
                    rows[4].append("│")
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
                rows[4].append(rows[0][-1])
                rows[1].append(ch)
                rows[2].append(("║" if on else "│") if down else " ")
                rows[3].append(rows[2][-1])
            w = width[c]
            cell = g.cells.get((r, c))
            if cell is None:
                for i in range(5):
                    rows[i].append(" " * w)
                continue
            if cell.box is not None:
                for i, s in enumerate(_box_lines(cell, w, pw)):
                    rows[i].append(s)
                rows[4].append(" │" + " " * (w - 4) + "│ " if not cell.box.first else " " * w)
                continue
            el = cell.elem
            rows[4].append(_center(el.name if el is not None else "", w))
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
        for i in (4, 0, 1, 2, 3):
            if (i == 2 and not (pw or box_info)) or (i == 3 and not box_ends) or \
                    (i == 4 and not any(cell.elem is not None and cell.elem.name
                                        for (rr, _), cell in g.cells.items() if rr == r)):
                continue
            if i in (0, 2) and r > 0 and not "".join(rows[i]).strip(" │║"):
                continue
            out.append("".join(rows[i]).rstrip())
    text = "\n".join(out) + "\n"
    return text.translate(ASCII) if ascii else text


def render_program_text(program: A.Program, *, ascii: bool = False,
                        blocks: BlockReader | None = None) -> str:
    parts = []
    for title_sec, rungs in program_sections(program):
        if title_sec:
            parts.append(f"== {title_sec} ==\n")
        for r in rungs:
            parts.append(render_text(r, ascii=ascii, blocks=blocks))
    return "\n".join(parts)


def program_sections(program: A.Program) -> list[tuple[str, list[A.Rung]]]:
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
