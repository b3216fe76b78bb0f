"""Pieces from DXF drawings (`softplc cut PART.dxf`), read with ezdxf.

Cut: the modelspace's LINE, ARC, CIRCLE and LWPOLYLINE entities (with bulges: a bulge b
between two vertices is an arc of included angle 4·atan(b), CCW for b > 0 [AutoCAD's
GetBulge]; the closing segment of a closed polyline too). An ARC runs CCW from its start to
its end angle about the extrusion (0, 0, 1) [ezdxf Arc]; an entity with the inverted
extrusion (0, 0, -1), as mirrored drawings have, is turned upright first (ezdxf.upright);
any other extrusion is not in the XY plane and refused. Other entity types (TEXT, SPLINE,
HATCH...) are not cut and listed in a warning.

Order: the entities in the file's order; each is cut from whichever of its ends the torch
already stands on (a contour drawn as separate LINEs in either direction is cut in one
pass), else from its start after a move with the torch off.
Units from $INSUNITS (0 unitless and 4 mm: mm; 1 in, 5 cm, 6 m converted); the work area
check, speeds and chord tolerance as for G-code (`piece.piece_from_gcode`).
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from softplc.limits import MAX_DXF_BYTES
from softplc.machines.cutting.geometry import SAME_POINT, Arc, GeometryError, Line, Point, distance
from softplc.machines.cutting.motion import DEFAULT_ACCEL, DEFAULT_SPEED
from softplc.machines.cutting.piece import WORK_AREA, Element, Piece, PieceError

#: $INSUNITS code -> mm per drawing unit (0: unitless, taken as mm).
MM_PER_UNIT = {0: 1.0, 4: 1.0, 1: 25.4, 5: 10.0, 6: 1000.0}
CUT_TYPES = ("LINE", "ARC", "CIRCLE", "LWPOLYLINE")

Shape = Line | Arc
#: Largest coordinate or radius read, in drawing units: a kilometre in mm, far beyond any
#: work area (the piece check refuses points outside it), small enough that the arc
#: arithmetic keeps its precision. NaN and the infinities are refused as well.
MAX_COORD = 1e6
#: Largest |bulge| of a polyline vertex: tan(θ/4) of an arc of θ = 359.9999° is 2.3e6;
#: beyond, the arc is a full circle to rounding (and 1e300 divided by zero).
MAX_BULGE = 1e7
_TAIL = 64  # bytes read at the end of a file for its EOF
BINARY_SENTINEL = b"AutoCAD Binary DXF"  # how a binary DXF file starts [ezdxf, AutoCAD]


def bulge_arc(p1: Point, p2: Point, bulge: float) -> Arc:
    """The arc from p1 to p2 of a polyline segment with this (nonzero) bulge: included
    angle θ = 4·atan(b), centre on the chord's perpendicular bisector at c/(2·tan(θ/2))
    to the left of p1 -> p2 (to the right when θ < 0 or |θ| > π, by the sign of tan)."""
    theta = 4.0 * math.atan(bulge)
    c = distance(p1, p2)
    ux, uy = (p2[0] - p1[0]) / c, (p2[1] - p1[1]) / c
    h = c / (2.0 * math.tan(theta / 2.0))
    centre = ((p1[0] + p2[0]) / 2 - uy * h, (p1[1] + p2[1]) / 2 + ux * h)
    return Arc(centre, p1, theta, p2)


def reverse(shapes: list[Shape]) -> list[Shape]:
    """The same path run from its end."""
    out: list[Shape] = []
    for s in reversed(shapes):
        if isinstance(s, Line):
            out.append(Line(s.end, s.start))
        else:
            out.append(Arc(s.centre, s.end, -s.sweep, None if s.full_circle else s.start))
    return out


def _shapes(e: object, scale: float) -> list[Shape]:
    """The entity's path in mm (WCS), start to end, in the drawing's direction."""
    kind = e.dxftype()  # type: ignore[attr-defined]
    dxf = e.dxf  # type: ignore[attr-defined]

    def mm(v: object) -> Point:
        return (_num(v[0], "a coordinate") * scale,  # type: ignore[index]
                _num(v[1], "a coordinate") * scale)  # type: ignore[index]

    if kind == "LINE":
        a, b = mm(dxf.start), mm(dxf.end)
        return [] if distance(a, b) <= SAME_POINT else [Line(a, b)]
    if kind in ("ARC", "CIRCLE"):
        c, r = mm(dxf.center), _num(dxf.radius, "the radius") * scale
        if r <= 0.0:
            raise GeometryError(f"radius {r:g}: a positive number expected")
        a0, a1 = (_num(dxf.start_angle, "the start angle"), _num(dxf.end_angle, "the end "
                  "angle")) if kind == "ARC" else (0.0, 0.0)
        sweep = math.radians((a1 - a0) % 360.0)
        a0 = math.radians(a0)
        start = (c[0] + r * math.cos(a0), c[1] + r * math.sin(a0))
        if sweep == 0.0:  # a CIRCLE, or an ARC from an angle to itself: the whole circle
            return [Arc(c, start, 2 * math.pi)]
        end = (c[0] + r * math.cos(a0 + sweep), c[1] + r * math.sin(a0 + sweep))
        return [Arc(c, start, sweep, end)]
    pts = [(_num(x, "a coordinate") * scale, _num(y, "a coordinate") * scale,
            _num(b, "a bulge", MAX_BULGE))  # (ezdxf gives numpy floats)
           for x, y, b in e.get_points("xyb")]  # type: ignore[attr-defined]
    if e.closed and pts:  # type: ignore[attr-defined]
        pts.append(pts[0])
    out: list[Shape] = []
    for (x1, y1, b), (x2, y2, _) in zip(pts, pts[1:], strict=False):
        p1, p2 = (x1, y1), (x2, y2)
        if distance(p1, p2) <= SAME_POINT:
            continue
        out.append(bulge_arc(p1, p2, b) if b else Line(p1, p2))
    return out


def _num(v: object, what: str, limit: float = MAX_COORD) -> float:
    """A number of the drawing, finite and within ±`limit`; GeometryError otherwise."""
    x = float(v)  # type: ignore[arg-type]
    if not (math.isfinite(x) and abs(x) <= limit):
        raise GeometryError(f"{what} of {x:g}: a finite number within ±{limit:g} expected")
    return x


def _line_of(file: str, handle: str) -> int:
    """The line of the file where the entity with this handle starts (group code 5 then
    the handle), for messages; 0 if it is not found."""
    try:
        with open(file, encoding="utf-8", errors="replace") as f:
            prev = ""
            for n, ln in enumerate(f, 1):
                ln = ln.strip()
                if prev == "5" and ln == handle:
                    return n - 1
                prev = ln
    except OSError:
        pass
    return 0


def _check_complete(file: str) -> None:
    """A DXF file ends with the group `0` / `EOF`: one cut short (a copy or a download
    that stopped) would otherwise be read up to where it stops, a part of the piece."""
    with open(file, "rb") as f:
        f.seek(max(os.fstat(f.fileno()).st_size - _TAIL, 0))
        tail = f.read().split()
    if tail[-2:] != [b"0", b"EOF"]:
        raise PieceError(f"{file}: not a readable DXF file: it does not end with 0 / EOF "
                         "(truncated?)")


def _upright(e: object, where: str) -> None:
    """Entities drawn with the extrusion (0, 0, -1) turned to (0, 0, 1), same curve."""
    ext = getattr(e.dxf, "extrusion", None)  # type: ignore[attr-defined]
    if ext is None or (abs(ext[0]) < 1e-9 and abs(ext[1]) < 1e-9 and ext[2] > 0):
        return
    if abs(ext[0]) < 1e-9 and abs(ext[1]) < 1e-9:
        from ezdxf.upright import upright

        upright(e)  # type: ignore[arg-type]
        return
    raise PieceError(f"{where}: extrusion {tuple(ext)} is not the XY plane")


def piece_from_dxf(path: str | Path, speed: float = DEFAULT_SPEED,
                   move_speed: float | None = None, accel: float = DEFAULT_ACCEL,
                   tolerance: float = 0.01, work_area: Point = WORK_AREA) -> Piece:
    """A piece from the LINE, ARC, CIRCLE and LWPOLYLINE entities of a DXF file."""
    import ezdxf
    from ezdxf.addons import iterdxf
    from ezdxf.filemanagement import dxf_file_info
    from ezdxf.lldxf.const import DXFError

    file = str(path)
    for name, v in (("speed", speed), ("accel", accel), ("tolerance", tolerance),
                    ("move_speed", move_speed or speed)):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise PieceError(f"{file}: {name} must be a positive number, not {v!r}")
    try:
        if os.stat(file).st_size > MAX_DXF_BYTES:
            raise PieceError(f"{file}: larger than {MAX_DXF_BYTES // 2**20} MiB")
        with open(file, "rb") as f:
            binary = f.read(len(BINARY_SENTINEL)) == BINARY_SENTINEL
        if binary:  # iterdxf reads text files only: the whole document then
            doc = ezdxf.readfile(file)
            entities, units = doc.modelspace(), doc.header.get("$INSUNITS", 0)
        else:  # streamed (ezdxf's iterdxf): never the whole document in memory
            _check_complete(file)
            entities, units = iterdxf.modelspace(file), dxf_file_info(file).insert_units
        return _piece(entities, units, file, speed, move_speed, accel, tolerance, work_area)
    except OSError as e:
        raise PieceError(f"{file}: cannot read the file: {e.strerror or e}") from None
    except (DXFError, ValueError, UnicodeDecodeError, IndexError, KeyError, TypeError,
            OverflowError, StopIteration, RuntimeError) as e:  # ezdxf's, on a garbled
        # or truncated file (OverflowError: 1e999 where an integer group code stands)
        why = str(e) if type(e).__name__ in str(e) else f"{type(e).__name__}: {e}"
        if isinstance(e, IndexError | StopIteration | RuntimeError):  # (in a generator,
            # a StopIteration becomes a RuntimeError)
            why = "it ends in the middle of an entry (truncated?)"
        raise PieceError(f"{file}: not a readable DXF file: {why}") from None


def _piece(entities: Iterable[Any], units: Any, file: str, speed: float,
           move_speed: float | None, accel: float, tolerance: float, work_area: Point
           ) -> Piece:
    """The piece of a drawing's modelspace entities (`piece_from_dxf`)."""
    if units not in MM_PER_UNIT:
        raise PieceError(f"{file}: $INSUNITS = {units}: only unitless, mm, cm, m and inch "
                         "drawings are read")
    scale = MM_PER_UNIT[units]
    elements: list[Element] = []
    skipped: Counter[str] = Counter()
    pos: Point = (0.0, 0.0)
    for e in entities:
        kind = e.dxftype()
        if kind not in CUT_TYPES:
            skipped[kind] += 1
            continue
        where = f"{kind} #{e.dxf.handle}"
        _upright(e, f"{file}: {where}")
        try:
            shapes = _shapes(e, scale)
        except (GeometryError, TypeError, ValueError) as err:
            line = _line_of(file, str(e.dxf.handle))
            raise PieceError(f"{file}:{line}: {where}: {err}" if line else
                             f"{file}: {where}: {err}") from None
        if not shapes:
            continue
        if distance(pos, shapes[0].start) > SAME_POINT >= distance(pos, shapes[-1].end):
            shapes = reverse(shapes)  # drawn the other way: cut on from where the torch is
        if distance(pos, shapes[0].start) > SAME_POINT:
            elements.append(Element(Line(pos, shapes[0].start, cut=False), False,
                                    move_speed or speed, where))
        elements.extend(Element(s, True, speed, where) for s in shapes)
        pos = shapes[-1].end
    warnings = [f"{file}: not cut (only {', '.join(CUT_TYPES)} are): "
                + ", ".join(f"{n} {k}" for k, n in sorted(skipped.items()))] if skipped else []
    if not any(el.cut for el in elements):
        raise PieceError(f"{file}: nothing to cut (no {', '.join(CUT_TYPES)} in the "
                         "modelspace)")
    piece = Piece(Path(file).stem, elements, (0.0, 0.0), accel, tolerance, work_area, file,
                  warnings)
    piece.check()
    return piece
