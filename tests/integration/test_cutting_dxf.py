"""DXF pieces (issue 23): LINE, ARC, CIRCLE and LWPOLYLINE with bulges, read with ezdxf,
from drawings each test makes with ezdxf."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from softplc.machines.cutting import Arc, Line, load_piece
from softplc.machines.cutting.dxf import bulge_arc
from softplc.machines.cutting.geometry import distance
from softplc.machines.cutting.piece import PieceError

ROOT = Path(__file__).resolve().parents[2]
PIECES = ROOT / "ladder_programs" / "pieces"
QUARTER = math.tan(math.pi / 8)  # the bulge of a 90 degree arc: tan(θ/4)


def drawing(units: int = 4):
    import ezdxf  # here, not at the top: every worker collects this module (0.7 s)

    doc = ezdxf.new()
    doc.header["$INSUNITS"] = units
    return doc, doc.modelspace()


def save(doc, tmp_path: Path, name: str = "part.dxf") -> Path:
    out = tmp_path / name
    doc.saveas(out)
    return out


def e3_polyline(msp, bulge: float = QUARTER) -> None:
    """E3's rounded rectangle as one closed LWPOLYLINE: a bulge on each corner's start."""
    msp.add_lwpolyline([(20, 10, 0), (40, 10, bulge), (50, 20, 0), (50, 40, bulge),
                        (40, 50, 0), (20, 50, bulge), (10, 40, 0), (10, 20, bulge)],
                       format="xyb", close=True)


def test_a_bulged_polyline_is_e3s_rounded_rectangle(tmp_path):
    doc, msp = drawing()
    e3_polyline(msp)
    piece = load_piece(save(doc, tmp_path))
    ref = load_piece(PIECES / "achaflanado.toml")
    arcs = [e.shape for e in piece.elements if isinstance(e.shape, Arc)]
    assert [a.centre for a in arcs] == [
        pytest.approx(c, abs=1e-9) for c in [(40, 20), (40, 40), (20, 40), (20, 20)]]
    assert all(a.sweep == pytest.approx(math.pi / 2, abs=1e-12) for a in arcs)
    assert piece.length("cut") == pytest.approx(ref.length("cut"), abs=1e-9)
    assert piece.area() == pytest.approx(1514.15927, abs=1e-5)  # 40 x 40 + 4 fillets ρ 10
    got = [s.end for s in piece.segments() if s.cut]
    want = [s.end for s in ref.segments() if s.cut]
    assert len(got) == len(want) == 4 + 4 * 18  # 18 chords per quarter at ε = 0.01
    assert max(distance(a, b) for a, b in zip(got, want, strict=True)) < 1e-9
    segs = piece.segments()
    assert segs[0].kind == "move" and segs[0].end == (20, 10)  # torch off to its start
    assert segs[-1].end == pytest.approx((20, 10), abs=1e-12)


@pytest.mark.parametrize("bulge,ccw", [(0.5, True), (-0.5, False), (2.0, True),
                                        (-1.0, False)])
def test_bulge_arcs_by_the_definition(bulge, ccw):
    """b = tan(θ/4), negative clockwise; 1 a half circle; > 1 more than half."""
    p1, p2 = (10.0, 10.0), (30.0, 10.0)
    arc = bulge_arc(p1, p2, bulge)
    theta = 4 * math.atan(bulge)
    assert arc.sweep == pytest.approx(theta) and arc.ccw == ccw
    assert arc.end == p2 and distance(arc.centre, p2) == pytest.approx(arc.radius)
    mid = arc.point_at(arc.sweep / 2)
    # the sagitta is b x half the chord, on the left of p1 -> p2 for b > 0
    assert mid[1] - 10 == pytest.approx(-bulge * 10)


def test_lines_and_arcs_drawn_either_way_are_chained(tmp_path):
    """A contour of separate entities, one LINE drawn backwards and an ARC (always CCW in
    DXF) met at its end: one move, then every entity from where the torch stands."""
    doc, msp = drawing()
    msp.add_line((10, 10), (40, 10))
    msp.add_arc((40, 20), 10, -90, 0)  # CCW from (40, 10) to (50, 20)
    msp.add_line((10, 20), (50, 20))  # drawn from the far end: cut reversed
    msp.add_line((10, 10), (10, 20))  # likewise
    msp.add_circle((100, 100), 5)
    msp.add_text("not cut")
    piece = load_piece(save(doc, tmp_path))
    segs = piece.segments()
    moves = [s for s in segs if s.kind == "move"]
    assert [m.end for m in moves] == [(10, 10), pytest.approx((105, 100))]
    cuts = [e.shape for e in piece.elements if e.cut]
    assert isinstance(cuts[2], Line) and cuts[2].start == pytest.approx((50, 20))
    assert cuts[3].start == pytest.approx((10, 20)) and cuts[3].end == pytest.approx((10, 10))
    assert isinstance(cuts[4], Arc) and cuts[4].full_circle
    assert piece.warnings and "1 TEXT" in piece.warnings[0]
    ideal = sum(e.shape.length for e in piece.elements if e.cut)
    assert ideal == pytest.approx(30 + 5 * math.pi + 40 + 10 + 10 * math.pi)


def test_an_arc_met_at_its_end_is_cut_clockwise(tmp_path):
    doc, msp = drawing()
    msp.add_line((10, 10), (50, 20))
    msp.add_arc((40, 20), 10, -90, 0)  # its end (50, 20) is where the line ends
    piece = load_piece(save(doc, tmp_path))
    arc = piece.elements[-1].shape
    assert arc.start == pytest.approx((50, 20)) and not arc.ccw
    assert piece.end == pytest.approx((40, 10))
    assert all(p.end[0] >= 40 - 1e-9 and p.end[1] <= 20 + 1e-9
               for p in piece.segments()[-arc.chord_count(0.01):])  # the lower right


def test_units_an_upside_down_arc_and_bad_files(tmp_path):
    doc, msp = drawing(units=1)  # inches
    msp.add_line((1, 1), (2, 1))
    # extrusion (0, 0, -1): the OCS x axis is the WCS -x; CCW about -Z is CW seen from +Z
    msp.add_arc((-3, 1), 1, 90, 180, dxfattribs={"extrusion": (0, 0, -1)})
    piece = load_piece(save(doc, tmp_path))
    assert piece.elements[1].shape == Line((25.4, 25.4), (50.8, 25.4))
    arc = piece.elements[-1].shape  # WCS (3, 2) -> (4, 1) CW, turned upright: CCW back
    assert arc.centre == pytest.approx((3 * 25.4, 25.4)) and arc.radius == pytest.approx(25.4)
    assert arc.start == pytest.approx((4 * 25.4, 25.4)) and arc.end == pytest.approx(
        (3 * 25.4, 2 * 25.4)) and arc.sweep == pytest.approx(math.pi / 2)
    with pytest.raises(PieceError, match="not a readable DXF|cannot read"):
        bad = tmp_path / "bad.dxf"
        bad.write_text("0\nSECTION\n2\nNONSENSE\n", encoding="utf-8")
        load_piece(bad)
    doc, msp = drawing()
    msp.add_text("only words")
    with pytest.raises(PieceError, match="nothing to cut"):
        load_piece(save(doc, tmp_path, "empty.dxf"))
    doc, msp = drawing(units=2)  # feet
    msp.add_line((1, 1), (2, 1))
    with pytest.raises(PieceError, match=r"\$INSUNITS = 2"):
        load_piece(save(doc, tmp_path, "feet.dxf"))
    doc, msp = drawing()
    msp.add_line((1, 1), (300, 1))
    with pytest.raises(PieceError, match="outside the 240 x 240 mm work area"):
        load_piece(save(doc, tmp_path, "big.dxf"))


def test_softplc_cut_previews_and_cuts_a_dxf(tmp_path, capsys):
    """`softplc cut PART.dxf --dry-run`, as for G-code (its --preview draws the loaded
    piece whatever the file: the same E3 piece's figure is test_cutting_pieces.py's
    test_cut_command_dry_run_preview_and_frames); then the PLC cuts it (in-process, the
    host's handshake): the torch-on trace within ε + 1 µm of the ideal rounded
    rectangle."""
    import numpy as np
    from test_cutting_table import COUNTS_PER_MM, homed

    from softplc.cli import main
    from softplc.machines.cutting.client import feed_plc

    doc, msp = drawing()
    e3_polyline(msp)
    f = save(doc, tmp_path)
    assert main(["cut", str(f), "--dry-run", "--speed", "10"]) == 0
    out = capsys.readouterr().out
    assert "77 segments (76 cut), cut 142.81192 mm" in out  # 4 lines + 4 x 18 chords
    piece = load_piece(f, speed=10.0)
    plc = homed()
    assert feed_plc(plc, piece, timeout=60) == 77
    origin = [plc.devices[a].position - plc[f"%MD{d}"] / 1000.0 * COUNTS_PER_MM
              for a, d in (("X", 112), ("Y", 114))]
    rows = np.array([(s[1], s[2], s[3]) for s in plc.devices["trace"].samples])
    lit = rows[:, 2] == 1
    x = (rows[lit, 0] - origin[0]) / COUNTS_PER_MM
    y = (rows[lit, 1] - origin[1]) / COUNTS_PER_MM
    assert piece.deviations(x, y).max() <= piece.tolerance + 0.001


def test_the_sample_plate_reads_as_the_readme_says():
    piece = load_piece(PIECES / "plate.dxf")
    assert not piece.warnings
    kinds = [type(e.shape).__name__ for e in piece.elements if e.cut]
    assert kinds.count("Arc") == 4 + 1 + 2 and kinds.count("Line") == 4 + 2
    assert sum(e.shape.length for e in piece.elements if e.cut) == pytest.approx(
        80 + 20 * math.pi + 12 * math.pi + 40 + 10 * math.pi)
