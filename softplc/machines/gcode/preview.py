"""Plot a program's path: pen-down moves solid, pen-up travel dashed (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

from softplc.errors import SoftPLCError
from softplc.machines.gcode.parser import GCodeConfig, Program, Segment, parse_file

_FORMATS = {".png", ".svg", ".pdf"}


def _runs(segments: list[Segment], pen_down: bool) -> list[list[tuple[float, float]]]:
    """Polylines of consecutive moves with the given pen state (one plot call per run)."""
    runs: list[list[tuple[float, float]]] = []
    for s in segments:
        if s.pen_down != pen_down or s.start == s.end:
            continue
        if runs and runs[-1][-1] == s.start:
            runs[-1].append(s.end)
        else:
            runs.append([s.start, s.end])
    return runs


def preview(program: Program | str | Path, out: str | Path,
            config: GCodeConfig | None = None, title: str | None = None) -> Path:
    """Draw `program` (a parsed Program or a G-code file path) into `out` (.png, .svg, .pdf).

    Returns the output path. The table outline is drawn so out-of-scale drawings show.
    """
    out = Path(out)
    if out.suffix.lower() not in _FORMATS:
        raise SoftPLCError(f"preview {out}: unsupported format {out.suffix!r}; "
                           f"use one of {', '.join(sorted(_FORMATS))}")
    if not isinstance(program, Program):
        program = parse_file(program, config)
    cfg = program.config

    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # no pyplot: no global state, no display

    fig = Figure(figsize=(7.5, 6), layout="constrained")
    ax = fig.add_subplot()
    w, h = cfg.table_width, cfg.table_height
    ax.plot([0, w, w, 0, 0], [0, 0, h, h, 0], color="0.7", linewidth=0.8, label="table area")
    first_down = first_up = True
    for run in _runs(program.segments, pen_down=False):
        xs, ys = zip(*run, strict=True)
        ax.plot(xs, ys, linestyle="--", color="tab:gray", linewidth=0.8,
                label="pen up (travel)" if first_up else None)
        first_up = False
    for run in _runs(program.segments, pen_down=True):
        xs, ys = zip(*run, strict=True)
        ax.plot(xs, ys, linestyle="-", color="tab:blue", linewidth=1.5,
                label="pen down" if first_down else None)
        first_down = False
    u, v = cfg.axes
    ax.set_xlabel(f"{u} (cm)")
    ax.set_ylabel(f"{v} (cm)")
    ax.set_aspect("equal")
    margin = 0.03 * max(w, h)
    ax.set_xlim(-margin, w + margin)
    ax.set_ylim(-margin, h + margin)
    ax.set_title(title or Path(program.file).name)
    fig.legend(loc="outside right upper", fontsize="small")  # never over the drawing
    fig.get_layout_engine().set(w_pad=0.12, h_pad=0.12)  # the legend off the image's edge
    try:
        fig.savefig(out)
    except OSError as e:
        raise SoftPLCError(f"cannot write preview {out}: {e.strerror or e}") from None
    return out
