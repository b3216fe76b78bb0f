"""Preview plots, the deviation metric, and `softplc draw --dry-run`."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from softplc.cli import main
from softplc.errors import SoftPLCError
from softplc.machines.drawing import TraceError, load_trace, max_deviation
from softplc.machines.drawing.deviation import distances_to_path
from softplc.machines.gcode import parse_gcode
from softplc.machines.gcode.preview import preview

SAMPLES = Path(__file__).resolve().parents[2] / "ladder_programs" / "samples"
LINE = "G00 X1 Z1\nY1\nG01 X3 Z1\nZ3\nY0\nG00 X10 Z10\n"


@pytest.fixture(scope="module")
def star_plots(tmp_path_factory) -> Path:
    """The star's preview and drawn trace, each as PNG and SVG, drawn once for the tests
    that look at them (each render costs a few tenths of a second of CPU)."""
    d = tmp_path_factory.mktemp("star")
    for ext in ("png", "svg"):
        preview(SAMPLES / "star.gcode", d / f"preview.{ext}")
        _draw_star(d / f"drawn.{ext}")
    return d


def test_preview_png_and_svg(tmp_path, star_plots):
    assert (star_plots / "preview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = preview(parse_gcode(LINE), tmp_path / "line.svg")
    text = svg.read_text()
    assert "<svg" in text and "pen down" in text and "pen up (travel)" in text
    assert "stroke-dasharray" in text  # the pen-up travel is dashed


def test_preview_rejects_unknown_format(tmp_path):
    with pytest.raises(SoftPLCError, match="unsupported format"):
        preview(parse_gcode(LINE), tmp_path / "x.jpg")


def test_deviation_from_tuples_in_steps_and_cm():
    prog = parse_gcode(LINE)
    trace = [
        (0.0, 0, 0, 0, 0),  # pen up: ignored even though far away
        (0.1, 111, 111, 1, 0),
        (0.2, 200, 114.11, 1, 0),  # 3 steps above the first pen-down line
        (0.3, 333, 250, 1, 2),  # on the second line
        (0.4, 1111, 1111, 0, 2),
    ]
    dev = max_deviation(prog.segments, trace, 111.11)
    assert dev.max_steps == pytest.approx(3.0, abs=1e-6)
    assert dev.max_units == pytest.approx(3.0 / 111.11)
    assert dev.at_time == 0.2 and dev.at_point == (200.0, 114.11)
    assert dev.samples == 3 and dev.missed_steps == 2
    assert "max deviation 3.00 steps" in str(dev)
    # Same answer against the integer step segments the PLC received.
    assert max_deviation(prog.steps(), trace).max_steps == pytest.approx(3.0, abs=0.5)


def test_deviation_from_csv_and_dicts(tmp_path):
    prog = parse_gcode(LINE)
    f = tmp_path / "trace.csv"
    f.write_text("t,x,z,pen,missed\n0,111,111,1,0\n1,333,200,1,0\n2,333,333,1,0\n")
    dev = max_deviation(prog.segments, f)
    assert dev.max_steps == pytest.approx(0.33, abs=1e-6)  # 0.33 steps left of X3 cm
    rows = [{"t": 0, "x": 222, "z": 116, "pen": 1, "missed": 0}]
    assert max_deviation(prog.segments, rows).max_steps == pytest.approx(4.89, abs=1e-6)
    assert load_trace(f).shape == (3, 5)


def test_trace_errors(tmp_path):
    f = tmp_path / "bad.csv"
    f.write_text("time,x,z\n0,1,2\n")
    with pytest.raises(TraceError, match="missing t,pen"):
        load_trace(f)
    f.write_text("t,x,z,pen,missed\n0,abc,1,1,0\n")
    with pytest.raises(TraceError, match="bad.csv:2"):
        load_trace(f)
    with pytest.raises(TraceError, match="cannot read trace"):
        load_trace(tmp_path / "missing.csv")


def test_deviation_edge_cases():
    prog = parse_gcode(LINE)
    nothing = max_deviation(prog.segments, [(0, 5, 5, 0, 0)])
    assert nothing.max_steps is None and nothing.samples == 0
    never_down = parse_gcode("X1 Z1\nX2 Z2")
    assert max_deviation(never_down.segments, [(0, 5, 5, 1, 0)]).max_steps == math.inf


def test_deviation_since_ignores_earlier_runs():
    prog = parse_gcode(LINE)
    trace = [(0.0, 2000, 2000, 1, 1), (1.0, 111, 111, 0, 1),  # an earlier run
             (2.0, 222, 112.11, 1, 1), (3.0, 333, 222, 1, 4)]
    assert max_deviation(prog.segments, trace).max_steps > 1000
    dev = max_deviation(prog.segments, trace, since=1.0)
    assert dev.max_steps == pytest.approx(1.0, abs=1e-6)
    assert dev.samples == 2 and dev.missed_steps == 3


def test_distance_to_degenerate_segment():
    pts = np.array([[3.0, 4.0]])
    path = np.array([[0.0, 0.0, 0.0, 0.0]])
    assert distances_to_path(pts, path)[0] == pytest.approx(5.0)


def test_cli_dry_run_with_preview(tmp_path, capsys):
    out = tmp_path / "circle.png"
    rc = main(["draw", str(SAMPLES / "circle.gcode"), "--dry-run", "--preview", str(out)])
    err = capsys.readouterr().err
    assert rc == 0 and out.exists() and "segments" in err and "preview written" in err


def test_cli_bad_gcode_lists_errors(tmp_path, capsys):
    bad = tmp_path / "bad.gcode"
    bad.write_text("G01 X1 Z1\nG01 X1..2\nG02 X30 Z1 R1\n")
    rc = main(["draw", str(bad), "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 1 and "bad.gcode:2:5" in err and "bad.gcode:3:12" in err
    assert "Traceback" not in err


def test_cli_options_reach_the_reader(tmp_path, capsys):
    src = tmp_path / "xy.gcode"
    src.write_text("G17 G21\nG00 Z5\nX100 Y100\nG01 Z-1\nX200\nG00 Z5\n")
    assert main(["draw", str(src), "--dry-run", "--plane", "XY"]) == 0
    assert "10.00 cm drawn" in capsys.readouterr().err
    assert main(["draw", str(src), "--dry-run", "--plane", "XY", "--table", "15x15"]) == 1
    assert "outside the 15 x 15 cm table" in capsys.readouterr().err


def test_cli_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["draw", "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    for opt in ("--host", "--port", "--preview", "--dry-run", "--start-at", "--trace",
                "--plane", "--steps-per-unit"):
        assert opt in text


def _star_trace() -> tuple[list, list, float]:
    """The star drawn exactly as programmed (it starts and ends at (0, 0)), in steps."""
    prog = parse_gcode((SAMPLES / "star.gcode").read_text())
    spu = prog.config.steps_per_unit
    samples, t = [], 0.0
    for s in prog.segments:
        for x, z in (s.start, s.end):
            samples.append((t, x * spu, z * spu, int(s.pen_down), 0))
            t += 0.1
    segs = [((s.start[0] * spu, s.start[1] * spu), (s.end[0] * spu, s.end[1] * spu))
            for s in prog.segments if s.pen_down]
    return samples, segs, spu


def _draw_star(out: Path) -> None:
    from softplc.machines.drawing.trace import plot_samples

    samples, segs, spu = _star_trace()
    plot_samples(samples, out, segs, units="units", unit_name="cm", steps_per_unit=(spu, spu),
                 travel_steps=(25 * spu, 25 * spu), title="trace.csv", full_area=True)


def test_plots_keep_the_legend_off_the_top_edge_and_name_axes_alike(star_plots):
    import matplotlib.image

    for name in ("preview.png", "drawn.png"):
        top = matplotlib.image.imread(star_plots / name)[:4, :, :3]
        assert top.min() == 1.0, f"{name}: something touches the image's top edge"
    for name in ("preview.svg", "drawn.svg"):  # matplotlib keeps each text as a comment
        text = (star_plots / name).read_text()
        assert "<!-- X (cm) -->" in text and "<!-- Z (cm) -->" in text, name


def test_drawn_plot_start_marker_visible_under_the_end_at_the_same_point(star_plots):
    import matplotlib.image

    rgb = matplotlib.image.imread(star_plots / "drawn.png")[:, :, :3]
    green = np.array([0x2C, 0xA0, 0x2C]) / 255  # tab:green: only the start marker uses it
    blue = np.array([0x1F, 0x77, 0xB4]) / 255  # tab:blue: the end marker
    near = lambda c: (np.abs(rgb - c).max(axis=2) < 0.05).sum()  # noqa: E731
    # both in the plot and in the legend: the plot's start ring shows around the end square
    assert near(green) > 100 and near(blue) > 40
