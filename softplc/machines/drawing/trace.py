"""The trace recorder: what the pen drew, for checking and plotting a run.

TOML options, table `[devices.NAME]` with `type = "trace"`. Put it after the axes and the
pen in the config, so that it sees their state of the same scan:

- `axes` (default `["X", "Z"]`): names of the two axis devices (`stepper` or
  `servo_axis`), horizontal (x) then vertical (z) axis of the drawing.
- `pen` (default `"pen"`): name of the `pen` (or `torch`) device; `""` for none (pen
  column 0).
- `csv` (path, default none): also write the samples to this CSV file, relative to the
  current directory, every `flush_every` seconds of simulated time and at `close()`.
- `flush_every` (duration > 0 of simulated time, default "1s"): CSV write period.
- `max_samples` (int 1..10000000, default 1000000): stop recording (and warn) after this
  many (a sample takes about 100 bytes of memory).
- `[devices.NAME.work]` (optional): the work frame the program keeps, for the web
  monitor's Machine tab, which then plots work coordinates as the host reports them:
  `origin` (two %MD: the work origin in the axes' counts as the controller reads them,
  the program's words), `area` (two mm > 0: the work area from the origin) and `homed`
  (a %M bit: the program has set the origin). A servo axis's counts are its controller's
  (user) position, which the trace's true position differs from by a constant.

A CSV file that cannot be written while the machine runs (a full disk, an I/O error) stops
the file, with one error message; the simulation and the samples in memory go on (a
trace must never stop the PLC). The first write (`record_to`) raises `TraceError` instead:
a file that cannot be written at start is the user's to fix.

A sample `(t, x, z, pen, missed)` is recorded at bind (t = 0) and after every scan that
changed something: t in seconds, x and z the axis positions in motor steps (a float on a
half step; a servo axis's true position in counts), pen 1 if down (torch lit), missed the
total of both axes' missed steps. `samples` is the
list; `to_csv(path)` writes it with the header `t,x,z,pen,missed`; `plot(path)` draws it.
"""

from __future__ import annotations

import logging
import math
import os
from typing import Any

from pydantic import Field

from softplc.config import FiniteFloat, PositiveDuration, Section
from softplc.devices.base import AxisDevice, Device, register_device
from softplc.errors import AddressError, ConfigCode, ConfigError, SoftPLCError
from softplc.machines.drawing.pen import Pen
from softplc.runtime.memory import MemoryImage
from softplc.twido.address import parse_address

log = logging.getLogger(__name__)

CSV_HEADER = "t,x,z,pen,missed"
MAX_SAMPLES = 10_000_000
#: cells across an axis's travel for the web view's samples: the Machine tab draws the
#: travel about 520 px wide, so a cell is under a quarter of a pixel
VIEW_CELLS = 2000
Sample = tuple[float, int | float, int | float, int, int]
Segment = tuple[tuple[float, float], tuple[float, float]]


class _NoPen:
    down = False


class WorkFrame(Section):
    """The program's work frame (module docstring)."""

    origin: list[str] = Field(min_length=2, max_length=2)
    area: list[FiniteFloat] = Field(min_length=2, max_length=2)
    homed: str = Field(min_length=1)


class TraceError(SoftPLCError):
    """The trace CSV file cannot be written."""


def _row(s: Sample) -> str:
    return f"{s[0]:.6f},{s[1]},{s[2]},{s[3]},{s[4]}\n"


@register_device("trace")
class Trace(Device):
    STATE = ("truncated", "_key", "_written", "_next_flush")
    RECORDS = ("samples",)

    class Options(Section):
        axes: list[str] = Field(["X", "Z"], min_length=2, max_length=2)
        pen: str = "pen"
        csv: str | None = Field(None, min_length=1)
        flush_every: PositiveDuration = 1.0
        max_samples: int = Field(1_000_000, ge=1, le=MAX_SAMPLES)
        work: WorkFrame | None = None

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.csv_path = options.csv
        self.flush_every = options.flush_every
        self.max_samples = options.max_samples
        self.samples: list[Sample] = []
        self.truncated = False
        self._x: Any = None
        self._z: Any = None
        self._pen: Any = _NoPen()
        self._key: tuple[Any, ...] = ()
        self._written = 0  # samples already in the CSV file
        self._next_flush = math.inf
        self.file_error = ""  # why the CSV file stopped being written ("" = it is not)
        self._mem: MemoryImage | None = None
        self._work: tuple[tuple[int, int], int] | None = None  # (%MD origin, %M homed)

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        x, z = self.options.axes
        self._x = self.peer(devices, x, AxisDevice, "axes[0]")
        self._z = self.peer(devices, z, AxisDevice, "axes[1]")
        if self.options.pen != "":
            self._pen = self.peer(devices, self.options.pen, Pen, "pen")
        work = self.options.work
        if work is not None:
            if min(work.area) <= 0:
                raise self.problem("work.area", f"expected two sizes > 0 mm, not {work.area}")
            ox, oz = (self._word(mem, a, "MD", "work.origin") for a in work.origin)
            self._work = ((ox, oz), self._word(mem, work.homed, "M", "work.homed"))
        self._mem = mem
        self.reset()

    def _word(self, mem: MemoryImage, address: str, kind: str, option: str) -> int:
        """The index of a plain %MD or %M (kind) the work frame reads."""
        try:
            ref = parse_address(address, mem.profile)
        except AddressError as e:
            raise self.problem(option, str(e), ConfigCode.ADDRESS) from None
        if ref.kind != kind or ref.bit is not None or ref.length or ref.offset is not None \
                or ref.field is not None:
            raise self.problem(option, f"expected a %{kind} address (got {address!r})",
                               ConfigCode.ADDRESS)
        return ref.index

    def reset(self) -> None:
        self.samples = []
        self.truncated = False
        self._written = 0
        self._next_flush = self.flush_every if self.csv_path else math.inf
        if self._x is not None:
            self._key = ()
            self.update(0.0, 0.0)

    def update(self, t: float, dt: float) -> None:
        x = self._x
        z = self._z
        key = (x.trace_position(), z.trace_position(), self._pen.down,
               x.missed() + z.missed())
        if key != self._key:
            self._key = key
            self._record(t, key)
        if t >= self._next_flush:
            self._next_flush = t + self.flush_every
            self.flush()

    def _record(self, t: float, key: tuple[Any, ...]) -> None:
        if len(self.samples) >= self.max_samples:
            if not self.truncated:
                self.truncated = True
                log.warning("%s: %d samples recorded, recording stops", self.name,
                            self.max_samples)
            return
        x, z, down, missed = key
        self.samples.append((t, x, z, 1 if down else 0, missed))

    def status(self) -> dict[str, Any]:
        return {"samples": len(self.samples)}

    def view(self, since_t: float) -> dict[str, Any] | None:
        # cell: the resolution a drawing of the whole travel needs (the web monitor sends
        # the samples that leave a cell: softplc.web.live.thin)
        view: dict[str, Any] = {"axes": list(self.options.axes), "pen": self.options.pen,
                                "samples": len(self.samples),
                                "cell": [_cell(a) for a in (self._x, self._z)]}
        if self._work is not None and self._mem is not None:
            (ox, oz), homed = self._work
            mw, work = self._mem.mw, self.options.work
            assert work is not None
            # the origin in the trace's frame: the program's counts + (true - controller's)
            origin = [mw.get_d(i) + a.trace_position() - _controller_position(a)
                      for i, a in ((ox, self._x), (oz, self._z))]
            view["work"] = {"origin": origin, "area": list(work.area),
                            "homed": bool(self._mem.m[homed]), "homed_by": work.homed,
                            "origin_words": list(work.origin)}
        return view

    # -- files ------------------------------------------------------------------------------
    def record_to(self, path: str | os.PathLike[str]) -> None:
        """From now on keep `path` (CSV) up to date with every sample (e.g. the daemon's
        `--trace`)."""
        self.csv_path = os.fspath(path)
        self._written = 0
        self._next_flush = 0.0
        self.file_error = ""
        try:
            self._append()
        except OSError as e:
            self.csv_path = None
            raise TraceError(f"trace file {path}: cannot write: {e.strerror or e}") from None

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write every sample, with the header `t,x,z,pen,missed`."""
        with open(path, "w", encoding="ascii") as f:
            f.write(CSV_HEADER + "\n")
            f.writelines(_row(s) for s in self.samples)

    def flush(self) -> None:
        """Append the samples not yet written to the `csv` file (if configured). A file
        that cannot be written is given up with one error (the samples stay in memory)."""
        if not self.csv_path:
            return
        try:
            self._append()
        except OSError as e:
            self.file_error = f"{self.csv_path}: {e.strerror or e}"
            log.error("%s: trace file %s; the trace file stops here (%d samples written), "
                      "the PLC goes on", self.name, self.file_error, self._written)
            self.csv_path = None
            self._next_flush = math.inf

    def _append(self) -> None:
        assert self.csv_path
        first = self._written == 0
        with open(self.csv_path, "w" if first else "a", encoding="ascii") as f:
            if first:
                f.write(CSV_HEADER + "\n")
            f.writelines(_row(s) for s in self.samples[self._written:])
        self._written = len(self.samples)

    def close(self) -> None:
        self.flush()

    def plot(self, path: str | os.PathLike[str], programmed: list[Segment] | None = None,
             units: str = "steps", title: str | None = None,
             full_area: bool = False) -> None:
        """Draw the trace to a PNG or SVG file (see `plot_samples`)."""
        plot_samples(self.samples, path, programmed, units=units,
                     steps_per_unit=(_per_unit(self._x), _per_unit(self._z)),
                     travel_steps=(_travel(self._x), _travel(self._z)),
                     title=title or None, name=self.name, full_area=full_area)


def _controller_position(axis: Any) -> float:
    """Where the axis's controller sees it: a servo axis's actual position (user counts),
    a stepper's own steps (its trace position)."""
    actual = getattr(axis, "actual", None)
    return axis.trace_position() if actual is None else float(actual)


def _cell(axis: Any) -> float:
    """An axis's travel / VIEW_CELLS; 0 (no thinning) for a travel without an end."""
    c = _travel(axis) / VIEW_CELLS
    return c if math.isfinite(c) and c > 0 else 0.0


def _per_unit(axis: Any) -> float:
    """Positions per drawing unit: a stepper's steps per unit, a servo's counts per mm."""
    return getattr(axis, "steps_per_unit", None) or axis.opt.counts_per_mm


def _travel(axis: Any) -> float:
    return getattr(axis, "travel_steps", None) or axis.axis_end()


def plot_samples(samples: Any, path: str | os.PathLike[str],
                 programmed: list[Segment] | None = None, *, units: str = "steps",
                 steps_per_unit: tuple[float, float] = (111.11, 111.11),
                 travel_steps: tuple[float, float] = (2778, 2778), title: str | None = None,
                 name: str = "trace", full_area: bool = False,
                 unit_name: str | None = None) -> None:
    """Draw trace samples (t, x, z, pen, missed) to a PNG or SVG file (by the extension).

    The optional `programmed` path (segments ((x0, z0), (x1, z1)) in steps) is drawn first,
    wide and light red; what the pen drew goes on top, thin solid black, so both stay
    visible where they coincide; pen-up travel thin dashed grey. The axes are in motor
    steps, or in drawing units with `units="units"` (`unit_name` labels them, e.g. "cm"),
    equal aspect. The view fits the drawing; `full_area=True` shows the whole table. The
    legend (table outline included) sits outside the plot area, on the right.
    """
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in (".png", ".svg"):
        raise ConfigError(f"trace plot: {os.fspath(path)!r} must end in .png or .svg")
    if units not in ("steps", "units"):
        raise ConfigError(f"trace plot: units must be 'steps' or 'units', not {units!r}")
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    samples = [tuple(s) for s in samples]
    sx = sz = 1.0
    if units == "units":
        sx, sz = 1 / steps_per_unit[0], 1 / steps_per_unit[1]
    scale = np.array([sx, sz])
    label = unit_name or units

    fig = Figure(figsize=(9, 7), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    # the table's drawing area, dotted; add_artist keeps it out of the autoscale
    w, h = travel_steps[0] * sx, travel_steps[1] * sz
    table = _rectangle((0, 0), w, h)
    ax.add_artist(table)
    handles: list[Any] = []
    if programmed:
        prog = np.array(programmed, dtype=float).reshape(-1, 2, 2) * scale
        ax.add_collection(LineCollection(prog, colors="tab:red", linewidths=4.0,
                                         alpha=0.35, zorder=2, capstyle="round"))
        handles.append(Line2D([], [], color="tab:red", lw=4.0, alpha=0.35,
                              label="programmed"))
    if samples:
        pts = np.array([(s[1], s[2]) for s in samples], dtype=float) * scale
        pen = np.array([s[3] for s in samples], dtype=bool)
        segs = np.stack([pts[:-1], pts[1:]], axis=1)
        moved = np.any(segs[:, 0] != segs[:, 1], axis=1)
        down = pen[:-1] & pen[1:]  # drawn only if the pen was down at both ends
        ax.add_collection(LineCollection(segs[moved & ~down], colors="0.55",
                                         linewidths=0.6, linestyles="--", zorder=3))
        ax.add_collection(LineCollection(segs[moved & down], colors="black",
                                         linewidths=1.0, zorder=4))
        # a drawing often ends where it started (0, 0): the start is a wide ring, the end a
        # small square drawn on top of it, so both stay visible
        start = dict(color="tab:green", marker="o", ms=12, mfc="none", mew=2)
        end = dict(color="tab:blue", marker="s", ms=5)
        ax.plot(*pts[0], zorder=5, **start)
        ax.plot(*pts[-1], zorder=6, **end)
        handles += [Line2D([], [], color="black", lw=1.0, label="drawn (pen down)"),
                    Line2D([], [], color="0.55", lw=0.6, ls="--", label="pen-up travel"),
                    Line2D([], [], ls="", label="start", **start),
                    Line2D([], [], ls="", label="end", **end)]
    handles.append(Line2D([], [], color=table.get_edgecolor(), lw=table.get_linewidth(),
                          ls=":", label="table area"))
    if full_area:
        ax.update_datalim([(0, 0), (w, h)])
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"X ({label})")  # the machine's axis names, as the G-code preview
    ax.set_ylabel(f"Z ({label})")
    missed = samples[-1][4] if samples else 0
    ax.set_title(f"{title or name}: {len(samples)} samples, {int(missed)} missed steps")
    fig.legend(handles=handles, loc="outside right upper", fontsize="small")
    fig.get_layout_engine().set(w_pad=0.12, h_pad=0.12)  # the legend off the image's edge
    ax.grid(True, lw=0.3)
    fig.savefig(path)


def _rectangle(xy: tuple[float, float], w: float, h: float) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle(xy, w, h, fill=False, ec="tab:blue", lw=0.5, ls=":", zorder=1)
