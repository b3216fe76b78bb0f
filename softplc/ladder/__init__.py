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

Modules by job: `tree` (IL rung -> tree), `live` (values for the live view), `layout`
(tree -> grid), `text` and `svg` (the renderers). The public names are re-exported here:
`render_program_svg`, `render_rung_svg`, `render_program_text`, `render_text`, `Live`...
"""

from __future__ import annotations

from softplc.ladder.layout import BoxRow, Cell, Grid, layout
from softplc.ladder.live import Live, block_summary, reads
from softplc.ladder.svg import CH, PAD, POWER_COLOUR, ROW_H, render_program_svg, render_rung_svg
from softplc.ladder.text import render_program_text, render_text
from softplc.ladder.tree import (
    ASCII,
    BOX_PINS,
    COIL,
    CONTACT,
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

__all__ = [
    "ASCII", "BOX_PINS", "Block", "BoxRow", "Branch", "CH", "COIL", "CONTACT", "Cell", "Elem",
    "Grid", "Junction", "Leaf", "Live", "Merge", "PAD", "POWER_COLOUR", "Par", "ROW_H", "Ser",
    "block_summary", "build", "layout", "reads", "render_program_svg", "render_program_text",
    "render_rung_svg", "render_text",
]
