"""G-code reader for the drawing table: text -> segments in drawing units (cm) -> motor steps.

Two dialects are read by the same code:

- ordinary G-code: one block per line, `N` optional, `( )` and `;` comments, G00 G01 G02
  G03 (R or I/J/K centre offsets), G04 dwell, G17/G18/G19, G20/G21, G90/G91, F;
- the seed's VB dialect: `N` starts a block, commas separate words, G70/G71 for inch/metric,
  `X`/`Z` in the drawing plane and `Y1`/`Y0` pen down/up.

The drawing plane is configured (`plane="XZ"` as on the seed table, or `"XY"`, `"YZ"`). The
remaining axis carries the pen: in "flag" mode (default when it is Y) a nonzero value puts
the pen down; in "depth" mode (default otherwise) the pen is down while that coordinate is
<= 0, as on a plotter driven by ordinary CAM output. G17/G18/G19 only confirm the plane; a
program that selects another plane is rejected (pass the plane it needs instead).

Problems are collected over the whole program and raised together as one `GCodeError`
(line:column for each, the warnings with them), so nothing is sent to a machine from a
program with an error. Unsupported codes (G40-G42, M codes, T, S...) are reported as
warnings and ignored.

Ambiguity: in the seed's XZ plane with Y as the pen flag, ordinary XY G-code such as
`G1 X10 Y10` would silently draw along X only. With `dialect="auto"` (default) a pen flag
other than 0/1, or a program that moves in X with Y words but never names Z, is refused
with a hint to `--plane XY`; `dialect="seed"` reads such Y words as the seed's pen flag
(nonzero = down, with a warning).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from softplc.errors import ConfigError, Diagnostic, ProgramError
from softplc.limits import MAX_GCODE_BYTES, MAX_NUMBER_DIGITS, BoundsError, read_bytes
from softplc.machines.gcode.arcs import (
    ArcGeometryError,
    Point,
    centre_from_radius,
    linearise_arc,
    sweep_angle,
)

#: Centimetres per program unit.
UNIT_CM = {"cm": 1.0, "mm": 0.1, "in": 2.54}

#: Largest step count the 16-bit %MW registers carry as a positive INT.
MAX_STEPS = 32767

#: What still counts as on the table's edge, cm (check_on_table).
EDGE_TOLERANCE_CM = 1e-5

PLANES = {"XY": 17, "XZ": 18, "YZ": 19}
DIALECTS = ("auto", "seed")
_PLANE_OF_G = {17: "XY", 18: "XZ", 19: "YZ"}
_OFFSET_LETTER = {"X": "I", "Y": "J", "Z": "K"}

_UNSUPPORTED_G = {
    40: "cutter compensation off", 41: "cutter compensation left",
    42: "cutter compensation right", 43: "tool length offset", 49: "tool length offset off",
    28: "return to home", 53: "machine coordinates", 54: "work offset", 55: "work offset",
    56: "work offset", 57: "work offset", 58: "work offset", 59: "work offset",
    61: "exact stop mode", 64: "path blending", 80: "canned cycle off",
    92: "coordinate offset", 93: "inverse time feed", 94: "feed per minute",
}
_KNOWN_LETTERS = set("GNXYZIJKRFP")
_WORD_RE = re.compile(r"([A-Za-z])[ \t]*([+-]?(?:\d+\.?\d*|\.\d+))")


class GCodeError(ProgramError):
    """A G-code program cannot be drawn. Carries every problem found (line:column), and the
    warnings of the same reading (shown with the errors, in line order)."""

    def __init__(self, diagnostics: list[Diagnostic] | Diagnostic | str,
                 warnings: list[Diagnostic] | None = None):
        super().__init__(diagnostics)
        self.warnings: list[Diagnostic] = list(warnings or [])

    def __str__(self) -> str:
        tagged = [(d, "") for d in self.diagnostics] + [(w, "warning: ") for w in self.warnings]
        tagged.sort(key=lambda dw: (dw[0].line, dw[0].column))
        return "\n".join(str(replace(d, message=tag + d.message)) for d, tag in tagged)


@dataclass(frozen=True)
class GCodeConfig:
    """How to read a program and what table it is drawn on.

    Lengths are in drawing units (cm): the table, tolerances and `steps_per_unit`.
    """

    plane: str = "XZ"
    pen: str | None = None  # "flag" | "depth"; None picks by pen axis (Y: flag)
    units: str = "cm"  # program unit before any G20/G21/G70/G71
    table_width: float = 25.0  # along the first plane axis
    table_height: float = 25.0  # along the second plane axis
    chord_tolerance: float = 0.01
    arc_radius_tolerance: float = 0.01  # allowed start/end radius mismatch of I/J/K arcs
    steps_per_unit: float = 111.11
    dialect: str = "auto"  # "auto": refuse XY G-code read as the seed's pen word; "seed"

    def __post_init__(self) -> None:
        plane = self.plane.upper()
        if plane == "ZX":
            plane = "XZ"
        if plane not in PLANES:
            raise ConfigError(f"drawing plane {self.plane!r}: expected one of XY, XZ, YZ")
        object.__setattr__(self, "plane", plane)
        if self.dialect not in DIALECTS:
            raise ConfigError(f"dialect {self.dialect!r}: expected one of {', '.join(DIALECTS)}")
        if self.pen not in (None, "flag", "depth"):
            raise ConfigError(f"pen mode {self.pen!r}: expected 'flag' or 'depth'")
        if self.units not in UNIT_CM:
            raise ConfigError(f"units {self.units!r}: expected one of {', '.join(UNIT_CM)}")
        for name in ("table_width", "table_height", "chord_tolerance",
                     "arc_radius_tolerance", "steps_per_unit"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number, not {value!r}")
        for name in ("table_width", "table_height"):
            if getattr(self, name) * self.steps_per_unit > MAX_STEPS:
                raise ConfigError(
                    f"{name} {getattr(self, name):g} x {self.steps_per_unit:g} steps/unit "
                    f"exceeds {MAX_STEPS} steps, the largest value a %MW register holds")

    @property
    def axes(self) -> tuple[str, str]:
        return self.plane[0], self.plane[1]

    @property
    def pen_axis(self) -> str:
        return next(a for a in "XYZ" if a not in self.plane)

    @property
    def pen_mode(self) -> str:
        if self.pen:
            return self.pen
        return "flag" if self.pen_axis == "Y" else "depth"


@dataclass(frozen=True, slots=True)
class Segment:
    """One straight move of the pen in the drawing plane, in drawing units (cm).

    kind: "rapid" (G00), "line" (G01), "arc" (a chord of G02/G03), "pen" (the pen changes
    without moving) or "dwell" (G04, `dwell` seconds, no motion).
    """

    start: Point
    end: Point
    pen_down: bool
    line: int
    kind: str = "line"
    feed: float | None = None
    dwell: float = 0.0

    @property
    def length(self) -> float:
        return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])


@dataclass(frozen=True, slots=True)
class StepSegment:
    """A segment as the PLC receives it: integer motor steps of both axes.

    `number` counts from 1 in the list `to_steps` returns (the `--start-at` number).
    """

    number: int
    start: tuple[int, int]
    end: tuple[int, int]
    pen_down: bool
    line: int
    kind: str = "line"
    dwell: float = 0.0


@dataclass
class Program:
    """A parsed program: its segments, the warnings, and the configuration it was read with."""

    segments: list[Segment]
    config: GCodeConfig
    warnings: list[Diagnostic] = field(default_factory=list)
    file: str = "<string>"

    def steps(self) -> list[StepSegment]:
        return to_steps(self.segments, self.config.steps_per_unit)

    def pen_down_length(self) -> float:
        return sum(s.length for s in self.segments if s.pen_down)


@dataclass
class _Word:
    letter: str
    value: float
    text: str
    col: int


@dataclass
class _State:
    pos: Point = (0.0, 0.0)
    motion: int = 1  # the seed's default: linear interpolation, pen up
    absolute: bool = True
    unit_cm: float = 1.0
    pen_down: bool = False
    pen_coord: float | None = None
    feed: float | None = None


def steps_of(value: float, steps_per_unit: float) -> int:
    """Round a drawing-unit coordinate to the nearest motor step (halves away from zero)."""
    x = value * steps_per_unit
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def to_steps(segments: list[Segment], steps_per_unit: float) -> list[StepSegment]:
    """Convert segments to integer steps, dropping moves that round to nothing.

    A zero-length step segment is kept only when it changes the pen or is a dwell.
    """
    out: list[StepSegment] = []
    pen = False
    for seg in segments:
        a = (steps_of(seg.start[0], steps_per_unit), steps_of(seg.start[1], steps_per_unit))
        b = (steps_of(seg.end[0], steps_per_unit), steps_of(seg.end[1], steps_per_unit))
        if out:
            a = out[-1].end  # chain exactly, whatever the rounding did
        if a == b and seg.pen_down == pen and seg.kind != "dwell":
            continue
        kind = "pen" if a == b and seg.kind != "dwell" else seg.kind
        out.append(StepSegment(len(out) + 1, a, b, seg.pen_down, seg.line, kind, seg.dwell))
        pen = seg.pen_down
    return out


def _strip_comments(text: str, lineno: int, file: str,
                    errors: list[Diagnostic]) -> str:
    """Blank out comments, keeping columns. `( )` comments do not nest or span lines."""
    out = list(text)
    i = 0
    n = len(text)
    while i < n:
        c = text[i]
        if c == ";":
            out[i:] = " " * (n - i)
            break
        if c == "(":
            j = text.find(")", i + 1)
            if j < 0:
                errors.append(Diagnostic("unclosed comment '('", file, lineno, i + 1,
                                         text[i:].strip()))
                out[i:] = " " * (n - i)
                break
            out[i:j + 1] = " " * (j + 1 - i)
            i = j + 1
            continue
        if c == ")":
            errors.append(Diagnostic("')' without '('", file, lineno, i + 1, ")"))
            out[i] = " "
        elif c in ",%":
            out[i] = " "  # commas separate words (seed); % marks tape start/end
        i += 1
    return "".join(out)


def _tokenize(text: str, lineno: int, file: str,
              errors: list[Diagnostic]) -> list[list[_Word]]:
    """Words of one line, split into blocks (an N word starts a new block)."""
    blocks: list[list[_Word]] = [[]]
    i, n = 0, len(text)
    while i < n:
        if text[i].isspace():
            i += 1
            continue
        m = _WORD_RE.match(text, i)
        end = m.end() if m else i
        if m and len(m.group(2)) > MAX_NUMBER_DIGITS:  # before float(): 1e400 is inf
            errors.append(Diagnostic(f"a number of {len(m.group(2))} characters", file,
                                     lineno, i + 1, m.group(0)[:20] + "...",
                                     f"at most {MAX_NUMBER_DIGITS}"))
            i = end
            continue
        if m and (end >= n or not (text[end].isdigit() or text[end] == ".")):
            letter = m.group(1).upper()
            word = _Word(letter, float(m.group(2)), m.group(0), i + 1)
            if letter == "N" and blocks[-1]:
                blocks.append([])
            blocks[-1].append(word)
            i = end
            continue
        j = i
        while j < n and not text[j].isspace():
            j += 1
        bad = text[i:j]
        what = "malformed number" if m else "malformed word"
        errors.append(Diagnostic(what, file, lineno, i + 1, bad,
                                 "a letter followed by a number, e.g. X12.5"))
        i = j
    return [b for b in blocks if b]


class _Reader:
    def __init__(self, config: GCodeConfig, file: str):
        self.cfg = config
        self.file = file
        self.errors: list[Diagnostic] = []
        self.warnings: list[Diagnostic] = []
        self.segments: list[Segment] = []
        self.st = _State(unit_cm=UNIT_CM[config.units])
        self.u_axis, self.v_axis = config.axes
        self.pen_axis = config.pen_axis
        self.pen_mode = config.pen_mode
        # ambiguity check (dialect "auto", pen flag): saw the plane's second axis at all;
        # the first block that moved along the first axis with a pen word
        self.saw_v = False
        self.first_u_with_pen: tuple[int, _Word] | None = None
        self.ambiguous = False  # an ambiguity error already said it

    def err(self, line: int, col: int, msg: str, text: str = "", expected: str = "") -> None:
        self.errors.append(Diagnostic(msg, self.file, line, col, text, expected))

    def warn(self, line: int, col: int, msg: str, text: str = "") -> None:
        self.warnings.append(Diagnostic(msg, self.file, line, col, text))

    def read(self, text: str) -> None:
        for lineno, raw in enumerate(text.splitlines(), start=1):
            stripped = raw.lstrip()
            if stripped.startswith("/"):
                self.warn(lineno, len(raw) - len(stripped) + 1,
                          "block delete '/' is not supported; the block is executed")
                raw = raw.replace("/", " ", 1)
            clean = _strip_comments(raw, lineno, self.file, self.errors)
            for block in _tokenize(clean, lineno, self.file, self.errors):
                self.block(lineno, block)

    # -- one block -------------------------------------------------------------------
    def block(self, line: int, words: list[_Word]) -> None:
        gcodes: list[_Word] = []
        args: dict[str, _Word] = {}
        for w in words:
            if w.letter == "G":
                gcodes.append(w)
            elif w.letter == "M":
                self.warn(line, w.col, f"M code {w.text} is not supported; ignored", w.text)
            elif w.letter not in _KNOWN_LETTERS:
                self.warn(line, w.col, f"word {w.letter} is not supported; ignored", w.text)
            elif w.letter in args:
                self.err(line, w.col, f"word {w.letter} appears twice in one block", w.text)
            else:
                args[w.letter] = w

        motion: _Word | None = None
        dwell: _Word | None = None
        groups: dict[str, _Word] = {}
        for g in gcodes:
            code = g.value
            if code != int(code):
                self.warn(line, g.col, f"{g.text} is not supported; ignored", g.text)
                continue
            c = int(code)
            group = ("motion" if c in (0, 1, 2, 3) else "plane" if c in (17, 18, 19)
                     else "units" if c in (20, 21, 70, 71) else "distance" if c in (90, 91)
                     else "dwell" if c == 4 else None)
            if group is None:
                why = _UNSUPPORTED_G.get(c, "unknown code")
                self.warn(line, g.col, f"G{c:02d} ({why}) is not supported; ignored", g.text)
                continue
            if group in groups:
                self.err(line, g.col, f"{g.text} conflicts with {groups[group].text} "
                         "in the same block", g.text)
                continue
            groups[group] = g
            if group == "plane":
                if _PLANE_OF_G[c] != self.cfg.plane:
                    self.err(line, g.col, f"G{c} selects the {_PLANE_OF_G[c]} plane but the "
                             f"table draws in the {self.cfg.plane} plane "
                             f"(choose the plane with --plane {_PLANE_OF_G[c]})", g.text)
            elif group == "units":
                self.st.unit_cm = UNIT_CM["in"] if c in (20, 70) else UNIT_CM["mm"]
            elif group == "distance":
                self.st.absolute = c == 90
            elif group == "motion":
                motion = g
            else:
                dwell = g

        if "F" in args:
            f = args["F"]
            if f.value <= 0:
                self.err(line, f.col, "feed F must be positive", f.text)
            else:
                self.st.feed = f.value * self.st.unit_cm

        if dwell is not None:
            self.do_dwell(line, dwell, args)
            return
        if "P" in args:
            self.warn(line, args["P"].col, "P outside a G04 block is ignored", args["P"].text)
        if motion is not None:
            self.st.motion = int(motion.value)
        if self.v_axis in args:
            self.saw_v = True
        if self.u_axis in args and self.pen_axis in args and self.first_u_with_pen is None:
            self.first_u_with_pen = (line, args[self.pen_axis])
        self.do_pen(line, args)
        self.do_motion(line, words[0].col, args)

    def do_dwell(self, line: int, g: _Word, args: dict[str, _Word]) -> None:
        w = args.get("P") or args.get("X")
        if w is None:
            self.err(line, g.col, "G04 needs a dwell time (P or X, in seconds)", g.text)
            return
        if w.value < 0:
            self.err(line, w.col, "dwell time must not be negative", w.text)
            return
        for letter in args:
            if letter not in ("P", "X", "N", "F") and letter != w.letter:
                self.warn(line, args[letter].col, f"{letter} is ignored in a G04 block",
                          args[letter].text)
        p = self.st.pos
        self.segments.append(Segment(p, p, self.st.pen_down, line, "dwell", self.st.feed,
                                     dwell=w.value))

    def do_pen(self, line: int, args: dict[str, _Word]) -> None:
        w = args.get(self.pen_axis)
        if w is None:
            return
        if self.pen_mode == "flag":
            if w.value not in (0.0, 1.0) and self.ambiguity_checked:
                self.err(line, w.col, f"{w.text} is not a pen word ({self.pen_axis}1 down, "
                         f"{self.pen_axis}0 up) of the seed dialect in the "
                         f"{self.cfg.plane} plane; {self.hint}", w.text)
                self.ambiguous = True
            elif w.value not in (0.0, 1.0):
                self.warn(line, w.col, f"pen word {w.text}: expected {self.pen_axis}1 (down) "
                          f"or {self.pen_axis}0 (up); taken as "
                          f"{'down' if w.value else 'up'}", w.text)
            self.st.pen_down = w.value != 0.0
        else:
            v = w.value * self.st.unit_cm
            if not self.st.absolute and self.st.pen_coord is not None:
                v += self.st.pen_coord
            self.st.pen_coord = v
            self.st.pen_down = v <= 0.0

    def target(self, args: dict[str, _Word]) -> Point:
        out = list(self.st.pos)
        for i, axis in enumerate((self.u_axis, self.v_axis)):
            w = args.get(axis)
            if w is not None:
                v = w.value * self.st.unit_cm
                out[i] = v if self.st.absolute else out[i] + v
        return (out[0], out[1])

    def do_motion(self, line: int, col: int, args: dict[str, _Word]) -> None:
        st = self.st
        has_axis = self.u_axis in args or self.v_axis in args
        plane_offsets = {_OFFSET_LETTER[self.u_axis], _OFFSET_LETTER[self.v_axis]}
        offsets = {k: args[k] for k in "IJK" if k in args}
        for k, w in offsets.items():
            if k not in plane_offsets:
                self.err(line, w.col, f"{k} is not a centre offset in the {self.cfg.plane} "
                         f"plane (use {' and '.join(sorted(plane_offsets))})", w.text)
        if st.motion in (0, 1):
            for k in [*offsets, *(["R"] if "R" in args else [])]:
                self.warn(line, args[k].col, f"{k} is ignored on a straight move", args[k].text)
        arc = st.motion in (2, 3)
        if not has_axis and not (arc and offsets):
            if "R" in args and arc:
                self.err(line, args["R"].col, "arc has R but no end point", args["R"].text)
            if self.pen_axis in args:
                # The pen moves without the pen carriage moving: a zero-length segment.
                if not self.segments or self.last_pen() != st.pen_down:
                    self.segments.append(Segment(st.pos, st.pos, st.pen_down, line, "pen",
                                                 st.feed))
            return
        start = st.pos
        end = self.target(args)
        first_axis = next((args[a] for a in (self.u_axis, self.v_axis) if a in args), None)
        where = first_axis.col if first_axis else col
        if arc:
            pts = self.arc_points(line, where, start, end, args, offsets)
            if pts is None:
                st.pos = end
                return
            kind = "arc"
        else:
            pts = [end]
            kind = "rapid" if st.motion == 0 else "line"
        if not self.check_on_table(line, where, pts):
            st.pos = end
            return
        if start == end and kind != "arc":
            if not self.segments or self.last_pen() != st.pen_down:
                self.segments.append(Segment(start, end, st.pen_down, line, "pen", st.feed))
            return
        prev = start
        for p in pts:
            self.segments.append(Segment(prev, p, st.pen_down, line, kind, st.feed))
            prev = p
        st.pos = end

    def last_pen(self) -> bool:
        return self.segments[-1].pen_down

    def arc_points(self, line: int, col: int, start: Point, end: Point,
                   args: dict[str, _Word], offsets: dict[str, _Word]) -> list[Point] | None:
        clockwise = self.st.motion == 2
        r_word = args.get("R")
        try:
            if r_word is not None and offsets:
                self.err(line, r_word.col, "arc gives both R and centre offsets; use one",
                         r_word.text)
                return None
            if r_word is not None:
                centre = centre_from_radius(start, end, r_word.value * self.st.unit_cm,
                                            clockwise)
                sweep = sweep_angle(start, end, centre, clockwise, full_if_closed=False)
            elif offsets:
                du = offsets.get(_OFFSET_LETTER[self.u_axis])
                dv = offsets.get(_OFFSET_LETTER[self.v_axis])
                k = self.st.unit_cm
                centre = (start[0] + (du.value * k if du else 0.0),
                          start[1] + (dv.value * k if dv else 0.0))
                r0 = math.dist(start, centre)
                r1 = math.dist(end, centre)
                if r0 == 0.0:
                    raise ArcGeometryError("arc centre is at its start point (radius 0)")
                if abs(r0 - r1) > self.cfg.arc_radius_tolerance:
                    raise ArcGeometryError(
                        f"the end point is {r1:.4g} from the centre but the start is "
                        f"{r0:.4g} (allowed difference {self.cfg.arc_radius_tolerance:g})")
                sweep = sweep_angle(start, end, centre, clockwise, full_if_closed=True)
            else:
                letters = " ".join(sorted(_OFFSET_LETTER[a] for a in self.cfg.plane))
                raise ArcGeometryError(f"arc needs R or centre offsets ({letters})")
            return linearise_arc(start, end, centre, sweep, self.cfg.chord_tolerance)
        except ArcGeometryError as e:
            self.err(line, r_word.col if r_word else col, str(e),
                     r_word.text if r_word else "")
            return None

    @property
    def ambiguity_checked(self) -> bool:
        return self.cfg.dialect == "auto" and self.pen_mode == "flag"

    @property
    def hint(self) -> str:
        return (f"if this is ordinary {self.u_axis}{self.pen_axis} G-code, draw it with "
                f"--plane {''.join(sorted(self.u_axis + self.pen_axis))} (or with "
                f"--dialect seed to read {self.pen_axis} as the pen flag)")

    def finish(self) -> None:
        """Whole-program checks, after the last block."""
        if self.ambiguity_checked and not self.saw_v and not self.ambiguous \
                and self.first_u_with_pen is not None:
            line, w = self.first_u_with_pen
            self.err(line, w.col, f"the program moves along {self.u_axis} with "
                     f"{self.pen_axis} words but never names {self.v_axis}: in the "
                     f"{self.cfg.plane} plane {self.pen_axis} only lifts and lowers the "
                     f"pen; {self.hint}", w.text)

    def check_on_table(self, line: int, col: int, pts: list[Point]) -> bool:
        w, h = self.cfg.table_width, self.cfg.table_height
        # An arc's chord points come from its centre, given to 6 decimals (I/K): an arc
        # tangent to an edge can land a few 1e-7 cm past it. 1e-5 cm (0.1 um, far below a
        # motor step) is no real excursion.
        eps = EDGE_TOLERANCE_CM
        for u, v in pts:
            if not (-eps <= u <= w + eps and -eps <= v <= h + eps):
                self.err(line, col, f"point {self.u_axis}{u:.4g} {self.v_axis}{v:.4g} cm is "
                         f"outside the {w:g} x {h:g} cm table")
                return False
        return True


def parse_gcode(text: str, config: GCodeConfig | None = None,
                file: str = "<string>") -> Program:
    """Read a whole program. Raises `GCodeError` listing every problem, with line:column."""
    cfg = config or GCodeConfig()
    reader = _Reader(cfg, file)
    reader.read(text)
    reader.finish()
    if reader.errors:
        raise GCodeError(reader.errors, reader.warnings)
    return Program(reader.segments, cfg, reader.warnings, file)


def parse_file(path: str | Path, config: GCodeConfig | None = None) -> Program:
    """Read a program file (UTF-8, or Latin-1 as old Windows editors wrote it)."""
    p = Path(path)
    try:
        data = read_bytes(p, MAX_GCODE_BYTES, "the file")
    except (OSError, BoundsError) as e:
        why = getattr(e, "strerror", None) or e
        raise GCodeError(Diagnostic(f"cannot read the file: {why}", str(p))) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    return parse_gcode(text, config, str(p))
