"""Pieces: an ordered list of shapes -> numbered segments (cut or move) for the table.

A piece comes from a small TOML file (`piece_from_dict`, schema below), from G-code through
the drawing host's reader (`piece_from_gcode`: XY plane, mm, G00 = move, G01/G02/G03 = cut,
no pen word) or from a DXF drawing (dxf.py); `load.load_piece` picks one by the file's
suffix. Coordinates are work coordinates in mm: (0, 0) is the homed corner, the work area
is [0, W] x [0, H] (240 x 240 by default, reference D1); every point is checked against it.

TOML (every key optional except the ops; unknown keys are errors)::

    name = "rounded rectangle"
    start = [0, 0]            # where the torch stands before the first op
    speed = 2.0               # cutting speed, mm/s
    move_speed = 10.0         # positioning speed, mm/s (default: speed)
    accel = 100.0             # path acceleration, mm/s² (split per axis by the PLC)
    chord_tolerance = 0.01    # mm, arcs (Newton curves: 60 chords or their own tolerance)
    work_area = [240, 240]    # mm

    [[op]]                    # kinds: move, line, arc, circle, contour, newton, dwell
    kind = "move"
    to = [20, 10]
    [[op]]
    kind = "arc"              # from the current point; sweep in degrees (CCW > 0)
    centre = [40, 20]         # or: end = [50, 20] with direction = "ccw" | "cw"
    sweep = 90

`circle` (centre, radius, start_angle deg, direction), `contour` (points, closed, radius =
fillet at every corner) and `newton` (x, y, samples or tolerance) start at their own first
point: a move (torch off) is inserted when the torch is elsewhere. Every op but `dwell`
(seconds: stand still, the torch lit if a cut follows: a pierce delay) takes `speed`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from softplc.config import error_lines
from softplc.machines.cutting import seed as thesis
from softplc.machines.cutting.geometry import (
    DEFAULT_TOLERANCE,
    NEWTON_SAMPLES,
    SAME_POINT,
    Arc,
    CuttingError,
    Fillet,
    GeometryError,
    Line,
    NewtonCurve,
    Point,
    distance,
    distance_to,
    distances_to,
    fillet,
    green_term,
)
from softplc.machines.cutting.motion import DEFAULT_ACCEL, DEFAULT_SPEED, MATLAB_CYCLE, split_line

#: Work area after homing, mm (reference D1: [0, 240] x [0, 240]).
WORK_AREA = (240.0, 240.0)
CUT, MOVE, DWELL = "cut", "move", "dwell"
#: The longest dwell one segment carries: the PLC times it with %TM1 (1 ms base, preset
#: 0-9999 [manual]); a longer G04 becomes several dwell segments in a row.
MAX_DWELL = 9.999


class PieceError(CuttingError):
    """A piece file or G-code program cannot be cut (names the file and key path / line)."""


# -- the TOML schema -----------------------------------------------------------------------

Vec = tuple[Annotated[float, Field(allow_inf_nan=False)],
            Annotated[float, Field(allow_inf_nan=False)]]
Speed = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _Op(_Model):
    speed: Speed | None = None


class MoveOp(_Op):
    kind: Literal["move"]
    to: Vec


class LineOp(_Op):
    kind: Literal["line"]
    to: Vec


class ArcOp(_Op):
    kind: Literal["arc"]
    centre: Vec
    sweep: Annotated[float, Field(ge=-360, le=360, allow_inf_nan=False)] | None = None
    end: Vec | None = None
    direction: Literal["ccw", "cw"] | None = None

    @model_validator(mode="after")
    def _one_way(self) -> ArcOp:
        if (self.sweep is None) == (self.end is None):
            raise ValueError("give either 'sweep' (degrees, CCW > 0) or 'end' (with "
                             "'direction')")
        if self.sweep is not None and self.direction is not None:
            raise ValueError("'direction' goes with 'end'; the sign of 'sweep' gives it")
        if self.sweep == 0:
            raise ValueError("'sweep' must not be 0")
        return self


class CircleOp(_Op):
    kind: Literal["circle"]
    centre: Vec
    radius: Speed
    start_angle: Annotated[float, Field(allow_inf_nan=False)] = 0.0
    direction: Literal["ccw", "cw"] = "ccw"


class ContourOp(_Op):
    kind: Literal["contour"]
    points: list[Vec] = Field(min_length=2)
    closed: bool = False
    radius: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 0.0


class DwellOp(_Model):
    kind: Literal["dwell"]
    seconds: Annotated[float, Field(ge=0, le=3600, allow_inf_nan=False)]


class NewtonOp(_Op):
    kind: Literal["newton"]
    x: list[Annotated[float, Field(allow_inf_nan=False)]]
    y: list[Annotated[float, Field(allow_inf_nan=False)]]
    samples: Annotated[int, Field(ge=1, le=100_000)] | None = None
    tolerance: Speed | None = None

    @model_validator(mode="after")
    def _one_rule(self) -> NewtonOp:
        if self.samples is not None and self.tolerance is not None:
            raise ValueError("give 'samples' or 'tolerance', not both")
        return self


Op = Annotated[MoveOp | LineOp | ArcOp | CircleOp | ContourOp | NewtonOp | DwellOp,
               Field(discriminator="kind")]


class PieceModel(_Model):
    name: str = ""
    start: Vec = (0.0, 0.0)
    speed: Speed = DEFAULT_SPEED
    move_speed: Speed | None = None
    accel: Speed = DEFAULT_ACCEL
    chord_tolerance: Speed = DEFAULT_TOLERANCE
    work_area: tuple[Speed, Speed] = WORK_AREA
    op: list[Op] = Field(min_length=1)


# -- the piece -----------------------------------------------------------------------------

@dataclass(frozen=True)
class Dwell:
    """G04 (or a TOML `dwell` op): stand still at `at` for `seconds`. The torch is lit if
    the next motion is a cut (a pierce delay, or a pause inside a contour), off otherwise,
    as a plasma cutter's (`regmap.piece_words` tells the PLC which)."""

    at: Point
    seconds: float

    @property
    def start(self) -> Point:
        return self.at

    @property
    def end(self) -> Point:
        return self.at


Shape = Line | Arc | NewtonCurve | Dwell


@dataclass(frozen=True)
class Element:
    """One shape of a piece with where it came from and its speed."""

    shape: Shape
    cut: bool
    speed: float
    where: str  # key path (op[3]) or G-code line (line 12)
    samples: int | None = None  # Newton curves: number of chords


@dataclass(frozen=True, slots=True)
class Segment:
    """One straight move the host sends: end point (mm), kind, path speed."""

    number: int  # 1-based
    kind: str  # "cut" (torch on), "move" (torch off) or "dwell" (no motion, `dwell` s)
    start: Point
    end: Point
    speed: float
    where: str
    dwell: float = 0.0

    @property
    def length(self) -> float:
        return distance(self.start, self.end)

    @property
    def cut(self) -> bool:
        return self.kind == CUT

    @property
    def pen_down(self) -> bool:
        """The torch is on (the drawing host's name, so its path helpers read segments)."""
        return self.kind == CUT


@dataclass
class Piece:
    name: str
    elements: list[Element]
    start: Point = (0.0, 0.0)
    accel: float = DEFAULT_ACCEL
    tolerance: float = DEFAULT_TOLERANCE
    work_area: Point = WORK_AREA
    file: str = "<string>"
    warnings: list[str] = field(default_factory=list)
    _segments: tuple[object, list[Segment]] = field(default=(None, []), init=False,
                                                     repr=False, compare=False)

    def segments(self, seed: bool | str = False) -> list[Segment]:
        """Numbered straight segments; seed=True (or "matlab", "cpu": the arc's variant)
        uses the thesis's arc and Newton code. Made once for the piece as it stands (a
        command asks for them several times: 400,000 segments each time for 200,000
        LINEs); the list is shared, not to be changed."""
        key = (seed, self.start, self.tolerance, len(self.elements))
        if self._segments[0] != key:
            self._segments = (key, self._make_segments(seed))
        return self._segments[1]

    def _make_segments(self, seed: bool | str) -> list[Segment]:
        out: list[Segment] = []
        pos = self.start
        for el in self.elements:
            if isinstance(el.shape, Dwell):
                left = el.shape.seconds
                while True:  # at least one segment (G04 P0 is kept: the host asked)
                    chunk = min(left, MAX_DWELL)
                    out.append(Segment(len(out) + 1, DWELL, pos, pos, el.speed, el.where,
                                       chunk))
                    left -= chunk
                    if left <= 1e-9:
                        break
                continue
            try:
                points = _points(el, self.tolerance, seed)
            except GeometryError as e:
                raise PieceError(f"{self.file}: {el.where}: {e}") from None
            for p in points:
                if distance(pos, p) <= SAME_POINT:
                    continue
                out.append(Segment(len(out) + 1, CUT if el.cut else MOVE, pos, p, el.speed,
                                   el.where))
                pos = p
        return out

    def check(self) -> None:
        """Every point inside the work area; PieceError naming the op otherwise."""
        w, h = self.work_area
        eps = 1e-9
        for where, (x, y) in [("start", self.start),
                              *((s.where, s.end) for s in self.segments())]:
            if not (-eps <= x <= w + eps and -eps <= y <= h + eps):
                raise PieceError(f"{self.file}: {where}: point ({x:.6g}, {y:.6g}) mm is "
                                 f"outside the {w:g} x {h:g} mm work area")

    @property
    def end(self) -> Point:
        segs = self.segments()
        return segs[-1].end if segs else self.start

    def length(self, kind: str = CUT, seed: bool | str = False) -> float:
        return sum(s.length for s in self.segments(seed) if s.kind == kind)

    def deviation(self, p: Point) -> float:
        """Distance from p to the nearest cut shape as designed (arcs and curves, not their
        chords): the trace check of the device round (<= chord tolerance + 1 µm)."""
        return min(distance_to(e.shape, p) for e in self.elements if e.cut)

    def deviations(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """`deviation` of many points at once (x and y arrays, mm)."""
        out = np.full(len(px), np.inf)
        for e in self.elements:
            if e.cut:
                np.minimum(out, distances_to(e.shape, px, py), out=out)
        return out

    def area(self) -> float:
        """Signed area enclosed by the cut lines and arcs as designed (not their chords),
        for a piece that cuts one closed contour (CCW > 0)."""
        cuts = [e.shape for e in self.elements if e.cut]
        if any(isinstance(c, NewtonCurve) for c in cuts):
            raise GeometryError("area: a Newton curve is not a closed contour")
        if not cuts or distance(cuts[0].start, cuts[-1].end) > 1e-6:
            raise GeometryError("area: the cuts do not form a closed contour")
        return sum(green_term(c) for c in cuts) / 2.0

    def duration(self) -> float:
        """Motion and dwell time of all segments with the corrected split (no handshake
        time)."""
        return sum(split_line(s.start, s.end, s.speed, self.accel).duration + s.dwell
                   for s in self.segments())


def _points(el: Element, tolerance: float, seed: bool | str) -> list[Point]:
    shape = el.shape
    variant = thesis.seed_variant(seed)
    if isinstance(shape, Arc):
        if variant:
            return thesis.thesis_arc_points(shape.centre, shape.start, shape.sweep,
                                            el.speed, MATLAB_CYCLE,
                                            cpu=variant == "cpu").points
        return shape.chords(tolerance)
    if isinstance(shape, NewtonCurve):
        if variant:
            return thesis.ThesisNewton(shape.xs, shape.ys).points()[1:]
        return shape.chords(samples=el.samples or NEWTON_SAMPLES)
    return shape.chords()


# -- building pieces -----------------------------------------------------------------------


class _Builder:
    def __init__(self, model: PieceModel, file: str):
        self.m = model
        self.file = file
        self.pos: Point = model.start
        self.elements: list[Element] = []
        self.move_speed = model.move_speed or model.speed

    def add(self, shape: Shape, cut: bool, speed: float | None, where: str,
            samples: int | None = None) -> None:
        v = speed or (self.m.speed if cut else self.move_speed)
        self.elements.append(Element(shape, cut, v, where, samples))
        self.pos = shape.end

    def go_to(self, p: Point, where: str) -> None:
        """A positioning move when the torch is not already at p."""
        if distance(self.pos, p) > SAME_POINT:
            self.add(Line(self.pos, p, cut=False), False, None, where)

    def op(self, i: int, op: MoveOp | LineOp | ArcOp | CircleOp | ContourOp | NewtonOp
           | DwellOp) -> None:
        where = f"op[{i}]"
        if isinstance(op, DwellOp):
            self.elements.append(Element(Dwell(self.pos, op.seconds), False, self.m.speed,
                                         where))
        elif isinstance(op, MoveOp | LineOp):
            cut = isinstance(op, LineOp)
            self.add(Line(self.pos, op.to, cut), cut, op.speed, where)
        elif isinstance(op, ArcOp):
            if op.sweep is not None:
                arc = Arc(op.centre, self.pos, math.radians(op.sweep))
            else:
                arc = Arc.through(op.centre, self.pos, op.end, op.direction != "cw")
            self.add(arc, True, op.speed, where)
        elif isinstance(op, CircleOp):
            a = math.radians(op.start_angle)
            p = (op.centre[0] + op.radius * math.cos(a), op.centre[1] + op.radius * math.sin(a))
            self.go_to(p, where)
            sweep = 2 * math.pi if op.direction == "ccw" else -2 * math.pi
            self.add(Arc(op.centre, p, sweep), True, op.speed, where)
        elif isinstance(op, ContourOp):
            self.contour(op, where)
        else:
            curve = NewtonCurve(tuple(op.x), tuple(op.y))
            self.go_to(curve.start, where)
            samples = (curve.samples_for(op.tolerance) if op.tolerance
                       else op.samples or NEWTON_SAMPLES)
            self.add(curve, True, op.speed, where, samples)

    def contour(self, op: ContourOp, where: str) -> None:
        pts = [tuple(p) for p in op.points]
        if op.closed and distance(pts[0], pts[-1]) <= SAME_POINT:
            pts.pop()  # closing point given explicitly
        n = len(pts)
        fillets: dict[int, Fillet] = {}
        if op.radius > 0:
            corners = range(n) if op.closed else range(1, n - 1)
            for k in corners:
                f = fillet(pts[k - 1], pts[k], pts[(k + 1) % n], op.radius)
                if f is not None:
                    fillets[k] = f
            sides = range(n) if op.closed else range(n - 1)
            for k in sides:
                j = (k + 1) % n
                need = (fillets[k].setback if k in fillets else 0.0) + (
                    fillets[j].setback if j in fillets else 0.0)
                side = distance(pts[k], pts[j])
                if need > side * (1 + 1e-9):
                    raise GeometryError(
                        f"fillet radius {op.radius:g}: the side {pts[k]} -> {pts[j]} is "
                        f"{side:.6g} mm long but its two fillets need {need:.6g} mm")
        first = fillets[0].t2 if 0 in fillets else pts[0]
        self.go_to(first, where)
        order = list(range(1, n)) + ([0] if op.closed else [])
        for k in order:
            f = fillets.get(k)
            if f is not None:
                self.add(Line(self.pos, f.t1), True, op.speed, where)
                self.add(f.arc, True, op.speed, where)
            else:
                self.add(Line(self.pos, pts[k]), True, op.speed, where)

    def piece(self) -> Piece:
        for i, op in enumerate(self.m.op):
            try:
                self.op(i, op)
            except GeometryError as e:
                raise PieceError(f"{self.file}: op[{i}] ({op.kind}): {e}") from None
        p = Piece(self.m.name or Path(self.file).stem, self.elements, self.m.start,
                  self.m.accel, self.m.chord_tolerance, self.m.work_area, self.file)
        p.check()
        return p


def piece_from_dict(data: dict, file: str = "<dict>") -> Piece:
    """Build and check a piece from the TOML structure (see the module docstring)."""
    try:
        model = PieceModel.model_validate(data)
    except ValidationError as e:
        raise PieceError("\n".join(f"{file}: {line}"
                                    for line in error_lines(e, PieceModel))) from None
    return _Builder(model, file).piece()


def piece_from_gcode(path: str | Path, speed: float = DEFAULT_SPEED,
                     move_speed: float | None = None, accel: float = DEFAULT_ACCEL,
                     tolerance: float = DEFAULT_TOLERANCE,
                     work_area: Point = WORK_AREA) -> Piece:
    """A piece from G-code read by `softplc.machines.gcode` in the XY plane, in mm (G20 switches to
    inches): G00 -> move, G01/G02/G03 -> cut, F in mm/min sets the cutting speed. The reader
    linearises arcs within `tolerance`; each G02/G03 is rebuilt into an `Arc` from its
    chords (so seed mode and the ideal-shape deviation see arcs), or kept as chords. A Z
    word (the drawing table's pen) is an error: the torch follows the motion codes. G04
    is a dwell (`Dwell`: the torch lit if a cut follows, the pierce delay)."""
    from softplc.machines.gcode import GCodeConfig, parse_file
    from softplc.machines.gcode.parser import UNIT_CM

    values = {"speed": speed, "move_speed": move_speed or speed, "accel": accel,
              "tolerance": tolerance, "work_area": work_area[0], "work_area height":
              work_area[1]}
    for name, v in values.items():
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise PieceError(f"{path}: {name} must be a positive number, not {v!r}")

    mm_per_cm = 1.0 / UNIT_CM["mm"]
    # The reader works in cm; its table check is replaced by the work-area check below
    # (in mm, with the same wording as TOML pieces), so its table is made large.
    cfg = GCodeConfig(plane="XY", units="mm", table_width=32767.0, table_height=32767.0,
                      chord_tolerance=tolerance / mm_per_cm, steps_per_unit=1.0)
    prog = parse_file(path, cfg)
    file = str(path)
    warnings = [str(w) for w in prog.warnings]
    elements: list[Element] = []
    pen_lines = sorted({s.line for s in prog.segments if s.kind == "pen" or s.pen_down})
    if pen_lines:
        raise PieceError(f"{file}: line {pen_lines[0]}: a Z (pen) word: the cutting table "
                         "has no pen axis; G00 moves with the torch off, G01-G03 cut")
    def mm(p: Point) -> Point:
        return (p[0] * mm_per_cm, p[1] * mm_per_cm)

    segs = prog.segments
    i = 0
    while i < len(segs):
        s = segs[i]
        if s.kind == "dwell":
            elements.append(Element(Dwell(mm(s.start), s.dwell), False, speed,
                                    f"line {s.line}"))
            i += 1
            continue
        cut = s.kind != "rapid"
        v = (s.feed * mm_per_cm / 60.0 if cut and s.feed else
             speed if cut else move_speed or speed)
        j = i + 1
        if s.kind == "arc":  # the chords of one G02/G03 block: rebuild the arc
            while j < len(segs) and segs[j].kind == "arc" and segs[j].line == s.line \
                    and segs[j].start == segs[j - 1].end:
                j += 1
            arc = _arc_from_chords([mm(s.start), *(mm(g.end) for g in segs[i:j])], tolerance)
            if arc is not None:
                elements.append(Element(arc, True, v, f"line {s.line}"))
                i = j
                continue
        for g in segs[i:j]:  # a straight move, or the chords of an arc not rebuilt
            elements.append(Element(Line(mm(g.start), mm(g.end), cut), cut, v,
                                    f"line {g.line}"))
        i = j
    piece = Piece(Path(file).stem, elements, (0.0, 0.0), accel, tolerance, work_area, file,
                  warnings)
    piece.check()
    return piece


def _circumcentre(a: Point, b: Point, c: Point) -> Point | None:
    d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if d == 0.0:
        return None
    sa, sb, sc = a[0] ** 2 + a[1] ** 2, b[0] ** 2 + b[1] ** 2, c[0] ** 2 + c[1] ** 2
    return ((sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1])) / d,
            (sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0])) / d)


#: How far a reader's chord point may be from the rebuilt circle (mm) for the arc to be kept.
ARC_FIT = 1e-6


def _arc_from_chords(pts: list[Point], tolerance: float) -> Arc | None:
    """The arc whose chords (by our rule) are `pts`, or None (then they stay lines).

    The G-code reader hands over an arc's chords only; the centre comes back as the
    circumcentre of three of them, the sweep as the sum of the chords' turns. Kept only when
    every point lies on that circle and the chord count matches, so two arcs written in one
    line, or I/J/K arcs whose radius drifts, stay as the reader's chords."""
    n = len(pts) - 1
    if n < 2:
        return None
    full = distance(pts[0], pts[-1]) <= SAME_POINT
    trio = (pts[0], pts[1], pts[2]) if full else (pts[0], pts[n // 2], pts[-1])
    centre = _circumcentre(*trio)
    if centre is None:
        return None
    r = distance(centre, pts[0])
    if any(abs(distance(centre, p) - r) > ARC_FIT for p in pts):
        return None
    sweep = 0.0
    for a, b in zip(pts, pts[1:], strict=False):
        u, w = (a[0] - centre[0], a[1] - centre[1]), (b[0] - centre[0], b[1] - centre[1])
        sweep += math.atan2(u[0] * w[1] - u[1] * w[0], u[0] * w[0] + u[1] * w[1])
    if full:
        sweep = math.copysign(2 * math.pi, sweep)
    try:
        arc = Arc(centre, pts[0], sweep, None if full else pts[-1])
    except GeometryError:
        return None
    return arc if arc.chord_count(tolerance) == n else None
