"""The trace recorder: what the pen drew, for checking and plotting a run.

TOML options, table `[devices.NAME]` with `type = "trace"`. Put it after the axes and the
pen in the config, so that it sees their state of the same scan:

- `axes` (default `["X", "Z"]`): names of the two `stepper` devices, horizontal (x) then
  vertical (z) axis of the drawing.
- `pen` (default `"pen"`): name of the `pen` device; `""` for none (pen column 0).
- `csv` (path, default none): also write the samples to this CSV file, relative to the
  current directory, every `flush_every` seconds of simulated time and at `close()`.
- `flush_every` (float > 0 seconds of simulated time, default 1.0): CSV write period.
- `max_samples` (int > 0, default 1000000): stop recording (and warn) after this many.

A sample `(t, x, z, pen, missed)` is recorded at bind (t = 0) and after every scan that
changed something: t in seconds, x and z the axis positions in motor steps (a float on a
half step), pen 1 if down, missed the total of both axes' missed steps. `samples` is the
list; `to_csv(path)` writes it with the header `t,x,z,pen,missed`; `plot(path)` draws it.
"""

from __future__ import annotations

import logging
import math
import os
from typing import Any

from ..errors import ConfigError
from ..runtime.memory import MemoryImage
from .base import Device, register_device
from .pen import Pen
from .stepper import Stepper, half_steps_to_steps

log = logging.getLogger(__name__)

CSV_HEADER = "t,x,z,pen,missed"
Sample = tuple[float, int | float, int | float, int, int]
Segment = tuple[tuple[float, float], tuple[float, float]]


class _NoPen:
    down = False


def _row(s: Sample) -> str:
    return f"{s[0]:.6f},{s[1]},{s[2]},{s[3]},{s[4]}\n"


@register_device("trace")
class Trace(Device):
    STATE = ("truncated", "_key", "_written", "_next_flush")
    RECORDS = ("samples",)

    def __init__(self, name: str, *, axes: Any = ("X", "Z"), pen: Any = "pen",
                 csv: Any = None, flush_every: Any = 1.0, max_samples: Any = 1_000_000):
        super().__init__(name)
        if not isinstance(axes, list | tuple) or len(axes) != 2:
            raise ConfigError(f"device {name!r}: axes must name two stepper devices "
                              f"(x then z), not {axes!r}")
        if csv is not None and (not isinstance(csv, str) or not csv):
            raise ConfigError(f"device {name!r}: csv must be a file path, not {csv!r}")
        if isinstance(flush_every, bool) or not isinstance(flush_every, int | float) \
                or not flush_every > 0:
            raise ConfigError(f"device {name!r}: flush_every must be > 0 seconds")
        if isinstance(max_samples, bool) or not isinstance(max_samples, int) \
                or max_samples < 1:
            raise ConfigError(f"device {name!r}: max_samples must be an integer > 0")
        self.axis_names = list(axes)
        self.pen_name = pen
        self.csv_path = csv
        self.flush_every = float(flush_every)
        self.max_samples = max_samples
        self.samples: list[Sample] = []
        self.truncated = False
        self._x: Any = None
        self._z: Any = None
        self._pen: Any = _NoPen()
        self._key: tuple[Any, ...] = ()
        self._written = 0  # samples already in the CSV file
        self._next_flush = math.inf

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._x = self.peer(devices, self.axis_names[0], Stepper, "axes[0]")
        self._z = self.peer(devices, self.axis_names[1], Stepper, "axes[1]")
        if self.pen_name != "":
            self._pen = self.peer(devices, self.pen_name, Pen, "pen")
        self.reset()

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
        key = (x._h, z._h, self._pen.down, x.missed_steps + z.missed_steps)
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
        xh, zh, down, missed = key
        self.samples.append((t, half_steps_to_steps(xh), half_steps_to_steps(zh),
                             1 if down else 0, missed))

    def status(self) -> dict[str, Any]:
        return {"samples": len(self.samples)}

    # -- files ------------------------------------------------------------------------------
    def record_to(self, path: str | os.PathLike[str]) -> None:
        """From now on keep `path` (CSV) up to date with every sample (e.g. the daemon's
        `--trace`)."""
        self.csv_path = os.fspath(path)
        self._written = 0
        self._next_flush = 0.0
        self.flush()

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write every sample, with the header `t,x,z,pen,missed`."""
        with open(path, "w", encoding="ascii") as f:
            f.write(CSV_HEADER + "\n")
            f.writelines(_row(s) for s in self.samples)

    def flush(self) -> None:
        """Append the samples not yet written to the `csv` file (if configured)."""
        if not self.csv_path:
            return
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
                     steps_per_unit=(self._x.steps_per_unit, self._z.steps_per_unit),
                     travel_steps=(self._x.travel_steps, self._z.travel_steps),
                     title=title or None, name=self.name, full_area=full_area)


def plot_samples(samples: Any, path: str | os.PathLike[str],
                 programmed: list[Segment] | None = None, *, units: str = "steps",
                 steps_per_unit: tuple[float, float] = (111.11, 111.11),
                 travel_steps: tuple[float, float] = (2778, 2778), title: str | None = None,
                 name: str = "trace", full_area: bool = False) -> None:
    """Draw trace samples (t, x, z, pen, missed) to a PNG or SVG file (by the extension).

    Pen-down moves are solid black, pen-up travel thin dashed grey, the optional
    `programmed` path (segments ((x0, z0), (x1, z1)) in steps) thin red on top. The
    axes are in motor steps, or in drawing units with `units="units"`, equal aspect.
    The view fits the drawing; `full_area=True` shows the whole table (0..travel).
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

    fig = Figure(figsize=(7, 7))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    # the table's drawing area, dotted; add_artist keeps it out of the autoscale
    w, h = travel_steps[0] * sx, travel_steps[1] * sz
    ax.add_artist(_rectangle((0, 0), w, h))
    handles = []
    if samples:
        pts = np.array([(s[1], s[2]) for s in samples], dtype=float) * scale
        pen = np.array([s[3] for s in samples], dtype=bool)
        segs = np.stack([pts[:-1], pts[1:]], axis=1)
        moved = np.any(segs[:, 0] != segs[:, 1], axis=1)
        down = pen[:-1] & pen[1:]  # drawn only if the pen was down at both ends
        ax.add_collection(LineCollection(segs[moved & ~down], colors="0.55",
                                         linewidths=0.6, linestyles="--", zorder=2))
        ax.add_collection(LineCollection(segs[moved & down], colors="black",
                                         linewidths=1.5, zorder=3))
        ax.plot(*pts[0], "o", color="tab:green", ms=5, zorder=5)
        ax.plot(*pts[-1], "s", color="tab:blue", ms=5, zorder=5)
        handles += [Line2D([], [], color="black", lw=1.5, label="pen down"),
                    Line2D([], [], color="0.55", lw=0.6, ls="--", label="pen up"),
                    Line2D([], [], color="tab:green", marker="o", ls="", label="start"),
                    Line2D([], [], color="tab:blue", marker="s", ls="", label="end")]
    if programmed:
        prog = np.array(programmed, dtype=float).reshape(-1, 2, 2) * scale
        ax.add_collection(LineCollection(prog, colors="tab:red", linewidths=0.8,
                                         alpha=0.7, zorder=4))
        handles.append(Line2D([], [], color="tab:red", lw=0.8, label="programmed"))
    if full_area:
        ax.update_datalim([(0, 0), (w, h)])
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"x ({units})")
    ax.set_ylabel(f"z ({units})")
    missed = samples[-1][4] if samples else 0
    ax.set_title(title or f"{name}: {len(samples)} samples, {int(missed)} missed steps")
    if handles:
        ax.legend(handles=handles, loc="best", fontsize="small")
    ax.grid(True, lw=0.3)
    fig.savefig(path)


def _rectangle(xy: tuple[float, float], w: float, h: float) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle(xy, w, h, fill=False, ec="tab:blue", lw=0.5, ls=":", zorder=1)
