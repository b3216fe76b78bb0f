"""Plot a piece: cuts solid, positioning moves dashed, dwells circled with their seconds,
optionally the thesis's (seed) path."""

from __future__ import annotations

from pathlib import Path

from softplc.errors import SoftPLCError
from softplc.machines.cutting.piece import DWELL, Piece
from softplc.machines.cutting.seed import seed_variant
from softplc.machines.gcode.preview import _FORMATS as FORMATS
from softplc.machines.gcode.preview import (
    _runs,  # polylines of consecutive segments with one pen state
)


def preview(piece: Piece, out: str | Path, seed: bool | str = False,
            title: str | None = None) -> Path:
    """Draw `piece` into `out` (.png, .svg, .pdf) in mm; seed=True overlays the path the
    thesis's algorithms would cut (arcs by round(θ/α), Newton without its last term)."""
    out = Path(out)
    if out.suffix.lower() not in FORMATS:
        raise SoftPLCError(f"preview {out}: unsupported format {out.suffix!r}; "
                           f"use one of {', '.join(sorted(FORMATS))}")
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # no pyplot: no global state, no display

    segs = piece.segments()
    fig = Figure(figsize=(8, 6))
    ax = fig.add_subplot()
    styles = {False: dict(linestyle="--", color="tab:gray", linewidth=0.9,
                           label="move (torch off)"),
              True: dict(linestyle="-", color="tab:blue", linewidth=1.6,
                          label="cut (torch on)")}
    for torch, style in styles.items():
        for i, run in enumerate(_runs(segs, torch)):
            xs, ys = zip(*run, strict=True)
            ax.plot(xs, ys, **(style if i == 0 else {**style, "label": None}))
    # one arrow per op / G-code line, on its middle segment: the direction of travel
    by_op: dict[str, list] = {}
    for sg in segs:
        by_op.setdefault(sg.where, []).append(sg)
    for group in by_op.values():
        sg = group[len(group) // 2]
        mid = ((sg.start[0] + sg.end[0]) / 2, (sg.start[1] + sg.end[1]) / 2)
        ax.annotate("", xy=sg.end if sg.length < 1e-3 else mid, xytext=sg.start,
                    arrowprops=dict(arrowstyle="-|>", color=styles[sg.cut]["color"],
                                    lw=0, mutation_scale=12))
    dwells = [sg for sg in segs if sg.kind == DWELL]
    for i, sg in enumerate(dwells):  # G04: where the carriage stands, and how long
        ax.plot(*sg.end, "o", markerfacecolor="none", color="tab:orange", markersize=9,
                label="dwell (G04), s" if i == 0 else None)
        ax.annotate(f"{sg.dwell:g}", sg.end, textcoords="offset points", xytext=(6, 6),
                    color="tab:orange", fontsize="small")
    if seed:
        for i, run in enumerate(_runs(piece.segments(seed=seed), True)):
            xs, ys = zip(*run, strict=True)
            ax.plot(xs, ys, color="tab:red", linewidth=0.9, linestyle=":",
                    label=f"thesis (seed mode, {seed_variant(seed)})" if i == 0 else None)
    ax.plot(*piece.start, "o", color="tab:green", label="start")
    ax.plot(*piece.end, "s", color="black", markersize=4, label="end")
    w, h = piece.work_area
    ax.plot([0, w, w, 0, 0], [0, 0, h, h, 0], color="0.75", linewidth=0.8,
            label=f"work area {w:g} x {h:g} mm")
    pts = [piece.start, *(s.end for s in segs)]
    xs, ys = zip(*pts, strict=True)
    span = max(max(xs) - min(xs), max(ys) - min(ys), 1.0)
    m = 0.06 * span
    ax.set_xlim(min(xs) - m, max(xs) + m)
    ax.set_ylim(min(ys) - m, max(ys) + m)
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.grid(True, color="0.92")
    cut = piece.length("cut")
    ax.set_title(f"{title or piece.name}\n{len(segs)} segments, cut {cut:.3f} mm, "
                 f"move {piece.length('move'):.3f} mm, about {piece.duration():.1f} s",
                 fontsize="medium")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small",
              borderaxespad=0.0)
    try:
        fig.savefig(out, bbox_inches="tight", dpi=110)
    except OSError as e:
        raise SoftPLCError(f"cannot write preview {out}: {e.strerror or e}") from None
    return out
