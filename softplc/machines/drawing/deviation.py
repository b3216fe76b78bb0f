"""How far the drawn trace strays from the programmed path.

A trace is a sequence of samples `(t, x_steps, z_steps, pen_down, missed_steps)`: a list of
tuples (or dicts / objects with those fields), or a CSV file with the header
`t,x,z,pen,missed` (the daemon's trace recorder, softplc/machines/drawing/trace.py). Only
samples with the pen down count: each one's distance to the nearest pen-down programmed segment is
measured, and the largest is reported, in steps and in drawing units (cm).
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from softplc.errors import SoftPLCError
from softplc.machines.gcode.parser import Segment, StepSegment

TRACE_COLUMNS = ("t", "x", "z", "pen", "missed")


class TraceError(SoftPLCError):
    """A trace cannot be read."""


@dataclass(frozen=True)
class Deviation:
    """The result of `max_deviation`.

    `max_steps` is None when the trace has no pen-down sample, and infinite when the pen
    went down although the program never lowers it.
    """

    max_steps: float | None
    max_units: float | None  # the same distance in drawing units (cm)
    at_time: float | None  # time of the worst sample
    at_point: tuple[float, float] | None  # worst sample, in steps
    samples: int  # pen-down samples measured
    missed_steps: int  # growth of the trace's running `missed` count over the samples used

    def __str__(self) -> str:
        if self.max_steps is None:
            return (f"no pen-down samples to compare ({self.samples} measured); "
                    f"missed steps: {self.missed_steps}")
        return (f"max deviation {self.max_steps:.2f} steps = {self.max_units:.4f} cm "
                f"at t={self.at_time:g}s {self.at_point} over {self.samples} pen-down "
                f"samples; missed steps: {self.missed_steps}")


def _row(sample: Any) -> tuple[float, ...]:
    if isinstance(sample, dict):
        return tuple(float(sample.get(k, 0) or 0) for k in TRACE_COLUMNS)
    if isinstance(sample, Sequence) and not isinstance(sample, str | bytes):
        vals = [float(v) for v in sample[:5]]
        return tuple(vals + [0.0] * (5 - len(vals)))
    return tuple(float(getattr(sample, k, 0) or 0) for k in TRACE_COLUMNS)


def load_trace(source: str | Path | Iterable[Any]) -> np.ndarray:
    """Samples as an (N, 5) float array of t, x, z, pen, missed.

    A path is read as CSV with a header naming at least t, x, z, pen (missed optional);
    anything else is taken as an iterable of samples.
    """
    if isinstance(source, str | Path):
        path = Path(source)
        try:
            with path.open(newline="") as f:
                reader = csv.DictReader(f)
                header = [h.strip() for h in (reader.fieldnames or [])]
                missing = [c for c in TRACE_COLUMNS[:4] if c not in header]
                if missing:
                    raise TraceError(f"trace {path}: header must name t,x,z,pen,missed; "
                                     f"missing {','.join(missing)}")
                rows = []
                for n, rec in enumerate(reader, start=2):
                    rec = {k.strip(): v for k, v in rec.items() if k}
                    try:
                        rows.append(_row(rec))
                    except (TypeError, ValueError):
                        raise TraceError(f"trace {path}:{n}: not a number in "
                                         f"{','.join(str(rec.get(k)) for k in TRACE_COLUMNS)}"
                                         ) from None
        except OSError as e:
            raise TraceError(f"cannot read trace {path}: {e.strerror or e}") from None
    else:
        try:
            rows = [_row(s) for s in source]
        except (TypeError, ValueError) as e:
            raise TraceError(f"trace sample is not (t, x, z, pen, missed): {e}") from None
    if not rows:
        return np.zeros((0, 5))
    return np.asarray(rows, dtype=float)


def _path_in_steps(segments: Sequence[Segment | StepSegment],
                   steps_per_unit: float) -> np.ndarray:
    """Pen-down segments as an (M, 4) array x0, z0, x1, z1 in steps."""
    rows = []
    for s in segments:
        if not s.pen_down:
            continue
        k = 1.0 if isinstance(s, StepSegment) else steps_per_unit
        rows.append((s.start[0] * k, s.start[1] * k, s.end[0] * k, s.end[1] * k))
    return np.asarray(rows, dtype=float).reshape(-1, 4)


def distances_to_path(points: np.ndarray, path: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """Distance from each point (N, 2) to the nearest segment of path (M, 4)."""
    out = np.empty(len(points))
    a = path[:, 0:2]
    d = path[:, 2:4] - a
    len2 = np.einsum("ij,ij->i", d, d)
    safe = np.where(len2 > 0, len2, 1.0)
    for lo in range(0, len(points), chunk):
        p = points[lo:lo + chunk, None, :]  # (n, 1, 2)
        t = np.einsum("nmk,mk->nm", p - a[None], d) / safe
        t = np.clip(np.where(len2 > 0, t, 0.0), 0.0, 1.0)
        nearest = a[None] + t[..., None] * d[None]
        dist = np.sqrt(((p - nearest) ** 2).sum(axis=2))
        out[lo:lo + chunk] = dist.min(axis=1)
    return out


def last_sample(path: str | Path) -> tuple[float, ...] | None:
    """The last sample of a trace CSV, or None if the file is missing or has no sample."""
    try:
        data = load_trace(path)
    except TraceError:
        return None
    return tuple(float(v) for v in data[-1]) if len(data) else None


def max_deviation(segments: Sequence[Segment | StepSegment],
                  trace: str | Path | Iterable[Any] | np.ndarray,
                  steps_per_unit: float = 111.11, since: float | None = None) -> Deviation:
    """Largest distance of pen-down trace samples from the programmed pen-down path.

    `segments` are the programmed segments, in cm (`Segment`) or steps (`StepSegment`).
    `since`: only samples with t > since count (the daemon's trace spans every run).
    """
    data = trace if isinstance(trace, np.ndarray) else load_trace(trace)
    data = data.reshape(-1, 5) if data.size else np.zeros((0, 5))
    missed_before = 0.0
    if since is not None:
        earlier = data[data[:, 0] <= since]
        missed_before = earlier[:, 4].max() if len(earlier) else 0.0
        data = data[data[:, 0] > since]
    missed = int(data[:, 4].max() - missed_before) if len(data) else 0
    down = data[data[:, 3] != 0]
    path = _path_in_steps(segments, steps_per_unit)
    if not len(down):
        return Deviation(None, None, None, None, 0, missed)
    if not len(path):  # the pen drew where nothing was programmed
        return Deviation(float("inf"), float("inf"), float(down[0, 0]),
                         (float(down[0, 1]), float(down[0, 2])), len(down), missed)
    dist = distances_to_path(down[:, 1:3], path)
    i = int(np.argmax(dist))
    worst = float(dist[i])
    return Deviation(worst, worst / steps_per_unit, float(down[i, 0]),
                     (float(down[i, 1]), float(down[i, 2])), len(down), missed)
