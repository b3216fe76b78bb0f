"""The program drawn as SVG."""

from __future__ import annotations

import html

from softplc.il import ast as A
from softplc.il.printer import format_instruction
from softplc.ladder.layout import BlockReader, Cell, layout
from softplc.ladder.live import Live
from softplc.ladder.text import box_inner_width, program_sections

CH, ROW_H, PAD = 7.2, 48, 20  # pixels per character, per row, margin
SYMBOL_H = 13  # the symbols' line above the addresses
VALUE_H = 8  # more per row in the live view: a value line clear of the next row's address
INFO_DY = 17  # a box row's info baseline below its wire (pin names sit on the wire, +4)


def render_program_svg(program: A.Program, blocks: BlockReader | None = None) -> str:
    """The whole program as one SVG document (hand-written, no dependencies)."""
    body: list[str] = []
    y = PAD
    width = 400.0
    for title_sec, rungs in program_sections(program):
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
            widths[c] = max(widths[c], box_inner_width(cell) + 2)
        elif cell.elem is not None:  # a value too: the next column (or the rail) clear of it
            widths[c] = max(widths[c], len(cell.elem.symbol), len(cell.elem.label),
                            len(cell.elem.name), len(cell.value))
    xs = [x0 + 10]
    for w in widths:
        xs.append(xs[-1] + (w + 4) * CH)
    # a line more per row for the symbols above the addresses, when the rung shows any
    extra = SYMBOL_H if any(c.elem is not None and c.elem.name for c in g.cells.values()) else 0
    row_h = ROW_H + extra + (VALUE_H if live is not None else 0)
    height = g.rows * row_h

    def wy(r: int) -> float:
        return top + r * row_h + 28 + extra

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
            _svg_box_row(cell, xa + 2 * CH, xb - 2 * CH, xa, xb, y, body, pw, row_h)
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
        if el.name:
            body.append(_text(xm, y - 27, el.name, size=11, anchor="middle", weight="bold"))
    for col, r1, r2, on in g.vlinks:
        body.append(_line(xs[col], wy(r1), xs[col], wy(r2), pw and on))
    return height + 24, xs[-1]


def _svg_box_row(cell: Cell, left: float, right: float, xa: float, xb: float, y: float,
                 body: list[str], pw: bool = False, row_h: float = ROW_H) -> None:
    """One row of a function block: its sides (top and title on the first row, bottom on
    the last), its pins and their wires."""
    b = cell.box
    assert b is not None and cell.elem is not None
    y1 = y - 26 if b.first else y - row_h + 14
    # meets the next row's y1; the last row's bottom leaves room for a line of info
    y2 = y + (INFO_DY + 3 if b.last and b.info else 14)
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
        body.append(_text((left + right) / 2, y + INFO_DY, b.info, size=10, anchor="middle",
                          fill="#0b4f8a"))  # a line below the pins' names, clear of them
    if b.left_wired:
        body.append(_line(xa, y, left, y, pw and cell.p_in))
    if b.right_wired:
        body.append(_line(right, y, xb, y, pw and cell.p_out))
