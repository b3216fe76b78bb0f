"""DXF and G-code input bounds (issue 31 item 4): NaN, infinite and huge numbers, truncated
files and arcs that would become millions of chords are clear errors naming the file, the
line and the entity, never a traceback or a MemoryError; a piece's segments are made
once, however often a command asks for them."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from softplc.machines.cutting import load_piece
from softplc.machines.cutting.piece import PieceError
from softplc.machines.gcode.arcs import MAX_ARC_SEGMENTS, ArcGeometryError, segments_needed
from softplc.machines.gcode.parser import GCodeError, parse_gcode

NAN, INF = float("nan"), float("inf")


def saved(tmp_path: Path, add, name: str = "part.dxf") -> Path:
    import ezdxf  # here, not at the top: every worker collects this module (0.7 s)

    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    msp.add_line((10, 10), (30, 20))
    add(msp)
    doc.saveas(tmp_path / name)
    return tmp_path / name


@pytest.mark.parametrize("add, words", [
    (lambda m: m.add_line((30, 20), (NAN, 20)), "LINE #30: a coordinate of nan"),
    (lambda m: m.add_line((NAN, NAN), (NAN, NAN)), "LINE #30: a coordinate of nan"),
    (lambda m: m.add_line((30, 20), (INF, 20)), "LINE #30: a coordinate of inf"),
    (lambda m: m.add_circle((50, 50), NAN), "CIRCLE #30: the radius of nan"),
    (lambda m: m.add_circle((50, 50), -5), "CIRCLE #30: radius -5"),
    (lambda m: m.add_arc((50, 50), 10, NAN, 90), "ARC #30: the start angle of nan"),
    (lambda m: m.add_lwpolyline([(30, 20, 1e300), (40, 20, 0)], format="xyb"),
     "LWPOLYLINE #30: a bulge of 1e+300"),
    (lambda m: m.add_lwpolyline([(30, 20, NAN), (40, 20, 0)], format="xyb"),
     "LWPOLYLINE #30: a bulge of nan"),
])
def test_non_finite_numbers_are_refused_at_their_line(tmp_path, add, words):
    path = saved(tmp_path, add)
    with pytest.raises(PieceError) as e:
        load_piece(path)
    line = next(n for n, ln in enumerate(path.read_text().splitlines(), 1)
                if ln.strip() == "30" and n > 1 and path.read_text().splitlines()[n - 2]
                .strip() == "5")
    assert f"{path}:{line - 1}: {words}" in str(e.value)


def test_a_truncated_file_is_a_clear_error(tmp_path):
    whole = saved(tmp_path, lambda m: m.add_circle((100, 100), 50)).read_bytes()
    cuts = range(200, len(whole), len(whole) // 40)
    for cut in cuts:
        part = tmp_path / f"cut{cut}.dxf"
        part.write_bytes(whole[:cut])
        with pytest.raises(PieceError, match=r"not a readable DXF file: \S"):
            load_piece(part)


def test_an_infinite_integer_group_is_a_clear_error(tmp_path):
    """Found by the fuzzer: 1e999 as an integer group's value (90: a polyline's vertex
    count) raised OverflowError inside ezdxf."""
    path = saved(tmp_path, lambda m: m.add_lwpolyline([(30, 20), (40, 20)]))
    lines = path.read_text().splitlines()
    at = next(n for n, ln in enumerate(lines) if ln.strip() == "LWPOLYLINE")
    at = next(n for n in range(at, len(lines)) if lines[n].strip() == "90")
    lines[at + 1] = "1e999"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(PieceError, match="not a readable DXF file"):
        load_piece(path)


def test_a_binary_dxf_is_still_read(tmp_path):
    import ezdxf

    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    doc.modelspace().add_line((10, 10), (30, 20))
    doc.saveas(tmp_path / "part.dxf", fmt="bin")
    assert [s.kind for s in load_piece(tmp_path / "part.dxf").segments()] == ["move", "cut"]


def test_an_arc_is_at_most_max_arc_segments_chords(tmp_path):
    path = saved(tmp_path, lambda m: m.add_circle((100, 100), 50))
    with pytest.raises(PieceError, match=f"more than {MAX_ARC_SEGMENTS} chords"):
        load_piece(path, tolerance=1e-12).segments()
    # the largest arc of the table at a 1 nm tolerance is still cut
    assert segments_needed(240.0, 2 * math.pi, 1e-6) < MAX_ARC_SEGMENTS
    for bad in ((NAN, 1.0, 0.01), (1.0, INF, 0.01), (1.0, 1.0, 0.0), (1e300, 6.0, 1e-3)):
        with pytest.raises(ArcGeometryError):
            segments_needed(*bad)


def test_segments_are_made_once(tmp_path):
    piece = load_piece(saved(tmp_path, lambda m: m.add_line((30, 20), (40, 40))))
    first = piece.segments()
    assert piece.segments() is first and len(first) == 3  # move, 2 cuts
    piece.start = (5.0, 5.0)  # another start: made again
    assert piece.segments() is not first


@pytest.mark.parametrize("text, col", [
    ("G1 X" + "9" * 400 + " Z1\n", 4),          # float() would make it inf
    ("G1 X1 Z1\nG2 X2 Z1 R" + "1" * 150 + "\n", 10),
])
def test_gcode_numbers_are_bounded(text, col):
    with pytest.raises(GCodeError) as e:
        parse_gcode(text)
    d = e.value.diagnostics[0]
    assert d.column == col and "characters" in d.message


def test_a_gcode_arc_needing_millions_of_chords_is_an_error():
    with pytest.raises(GCodeError, match="chords"):
        parse_gcode("G1 X1 Z1\nG2 X1.000001 Z1 R-1" + "0" * 80 + "\n")
