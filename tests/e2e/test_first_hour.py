"""First-hour rough edges (issue 9, points 15-17): shared program/config arguments,
`ladder --config`, REPL status and trace errors, PLC repr, check wording, missing files,
the port-in-use hint, `make bench` saying what it installs."""

from __future__ import annotations

import socket
import subprocess
from pathlib import Path

import pytest

from softplc.cli import build_parser
from softplc.cli import main as softplc
from softplc.debug.session import Session
from softplc.plc import PLC

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"
SAMPLE = Path(__file__).parents[1] / "debug_sample.il"
CONFIG = Path(__file__).parents[1] / "debug_sample.toml"


# ---- 15: one set of program/config arguments; ladder --config ---------------------------------
@pytest.mark.parametrize("command", ["check", "run", "repl", "ladder"])
def test_every_command_takes_the_same_program_and_config_arguments(command):
    args = build_parser().parse_args([command, "p.il", "--config", "m.toml"])
    assert args.program == Path("p.il") and args.config == Path("m.toml")


def test_ladder_with_config_shows_timer_type_base_and_preset(capsys):
    assert softplc(["ladder", str(LP / "star_delta.il"), "--config",
                    str(LP / "star_delta.toml"), "--rung", "3"]) == 0
    out = capsys.readouterr().out
    assert "TON 100ms" in out and "P=50" in out
    assert softplc(["ladder", str(LP / "star_delta.il"), "--rung", "3"]) == 0
    assert "TON" not in capsys.readouterr().out  # without a config there is nothing to show


def test_ladder_svg_with_config(tmp_path):
    svg = tmp_path / "l.svg"
    assert softplc(["ladder", str(LP / "star_delta.il"), "--config",
                    str(LP / "star_delta.toml"), "--svg", str(svg)]) == 0
    assert "TON 100ms" in svg.read_text() and "P=50" in svg.read_text()


@pytest.mark.parametrize("command", ["check", "ladder", "repl"])
def test_missing_program_or_config_says_no_such_file(command, tmp_path, capsys):
    assert softplc([command, str(tmp_path / "nosuch.il")]) == 1
    err = capsys.readouterr().err
    assert "nosuch.il: no such file (program)" in err and ":0:0" not in err
    assert softplc([command, str(LP / "star_delta.il"), "--config",
                    str(tmp_path / "nosuch.toml")]) == 1
    assert "nosuch.toml: no such file (configuration)" in capsys.readouterr().err


def test_check_says_1_rung_in_the_singular(tmp_path, capsys):
    p = tmp_path / "one.il"
    p.write_text("LD %I0.0\nST %Q0.0\n")
    assert softplc(["check", str(p)]) == 0
    assert "OK - 1 rung, 2 instructions" in capsys.readouterr().out


# ---- 16: REPL status, trace errors, PLC repr, port in use ------------------------------------
def test_time_stopped_at_a_breakpoint_is_not_scan_time(monkeypatch):
    import softplc.runtime.engine as engine

    now = [1000.0]
    monkeypatch.setattr(engine.time, "perf_counter", lambda: now[0])
    s = Session(PLC.from_file(SAMPLE, config=CONFIG), SAMPLE)
    s.execute("break 3")
    s.execute("continue")
    assert s.pos == (3, 0)
    now[0] += 3600.0  # an hour looking at the breakpoint
    s.execute("delete 1")
    s.execute("continue")
    assert s.plc.stats.max < 1.0
    assert "max 0 us" in s.execute("status")


def test_trace_to_a_missing_folder_is_a_clear_message(tmp_path):
    s = Session(PLC.from_file(SAMPLE, config=CONFIG), SAMPLE)
    out = s.execute(f"trace %M0 to {tmp_path}/nodir/x.csv")
    assert out == f"error: cannot write {tmp_path}/nodir/x.csv: the folder " \
                  f"{tmp_path}/nodir does not exist"
    assert s.trace_file is None and "Errno" not in out


def test_plc_repr_shows_state_time_scans_and_io_that_is_on():
    plc = PLC.from_source("LD %I0.0\nST %Q0.1\nST %Q0.3\n")
    plc["%I0.0"] = 1
    plc.scan(3)
    assert repr(plc) == "<PLC <string> RUN t=0.030s scans=3 on: %I0.0 %Q0.1 %Q0.3>"


def test_port_in_use_suggests_another_port(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert softplc(["run", str(LP / "star_delta.il"), "--config",
                        str(LP / "star_delta.toml"), "--port", str(port),
                        "--state", str(tmp_path / "s.state")]) == 1
    err = capsys.readouterr().err
    assert "--port" in err and "PORT=" in err and "make run" in err


# ---- 17: make bench says what it installs ----------------------------------------------------
def test_make_bench_says_what_it_installs_and_why():
    out = subprocess.run(["make", "-n", "bench"], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout
    assert "libmodbus-dev" in out and "installing" in out and "C ceiling" in out


# ---- 13: make draw's plot, trace end and progress ---------------------------------------------
def test_progress_bar_shows_elapsed_time_and_eta():
    import io

    from softplc.machines.drawing.host import ProgressBar

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    now = [0.0]
    out = Terminal()
    bar = ProgressBar(10, out, clock=lambda: now[0])
    bar.update(0)
    now[0] = 20.0
    bar.update(4)
    assert "4/10 0:20 elapsed, ETA 0:30" in out.getvalue()
    now[0] = 3700.0
    bar.update(10)
    assert out.getvalue().endswith("10/10 1:01:40 elapsed\x1b[K")


def test_a_pen_up_sample_mid_drawing_is_not_the_end_of_the_trace(tmp_path):
    from softplc.machines.drawing.command import _wait_for_trace

    csv = tmp_path / "t.csv"
    csv.write_text("t,x,z,pen,missed\n1.0,0,0,0,0\n2.0,100,0,1,0\n3.0,100,0,0,0\n")
    assert not _wait_for_trace(str(csv), 0.5, (200, 0), timeout=0.2)  # a travel, not the end
    with csv.open("a") as f:
        f.write("4.0,200,0,1,0\n5.0,200,0,0,0\n")
    assert _wait_for_trace(str(csv), 0.5, (200, 0), timeout=0.2)


def test_drawn_plot_is_in_cm_with_both_paths_and_the_legend_outside(tmp_path):
    import matplotlib.figure

    from softplc.machines.drawing.trace import plot_samples

    saved = {}
    real_savefig = matplotlib.figure.Figure.savefig

    def keep(fig, path, *a, **kw):
        saved["fig"] = fig
        return real_savefig(fig, path, *a, **kw)

    samples = [(0, 0, 0, 0, 0), (1, 1111, 0, 1, 0), (2, 1111, 1111, 1, 0), (3, 1111, 1111, 0, 0)]
    prog = [((0, 0), (1111, 0)), ((1111, 0), (1111, 1111))]
    mp = pytest.MonkeyPatch()
    mp.setattr(matplotlib.figure.Figure, "savefig", keep)
    try:
        plot_samples(samples, tmp_path / "d.png", prog, units="units", unit_name="cm")
    finally:
        mp.undo()
    fig = saved["fig"]
    ax = fig.axes[0]
    assert ax.get_xlabel() == "X (cm)" and ax.get_ylabel() == "Z (cm)"  # as the preview
    assert ax.get_xlim()[1] < 20  # 10 cm drawn, not 1111 steps
    prog_lines, _, drawn = ax.collections  # programmed first, drawn last: on top
    assert drawn.get_zorder() > prog_lines.get_zorder()
    assert drawn.get_linewidth()[0] < prog_lines.get_linewidth()[0]
    legend = fig.legends[0]
    labels = [t.get_text() for t in legend.get_texts()]
    assert "table area" in labels and "programmed" in labels
    fig.canvas.draw()
    box = legend.get_window_extent()
    assert box.x0 >= ax.get_window_extent().x1  # right of the plot area, not over it


def test_the_docs_config_error_example_is_what_softplc_prints(tmp_path, capsys):
    from docs_util import fenced, page

    shown = fenced(page("docs/configuration.md"), "checked against one typed schema", "text")
    cfg = tmp_path / "m.toml"
    cfg.write_text('scan_period = 10\n[timers."%TM0"]\npreset = "3"\n[devices.X]\n'
                   'type = "stepper"\nphases = ["%Q1.0", "%Q1.1", "%Q1.2", "%Q1.3"]\n'
                   'travl = 3\n')
    prog = tmp_path / "p.il"
    prog.write_text("LD %TM0.Q\nST %Q0.0\n")
    assert softplc(["check", str(prog), "--config", str(cfg)]) == 1
    err = capsys.readouterr().err
    assert err.replace(str(tmp_path) + "/", "") == "softplc: error: " + shown


# ---- 12: the README says how to reach `softplc` before its first bare `softplc` example ------
def test_readme_says_to_activate_the_venv_before_the_first_softplc_command():
    import re

    readme = (ROOT / "README.md").read_text()
    first_command = re.search(r"^(?:\$ )?softplc \w", readme, re.M)
    activate = readme.index(". .venv/bin/activate")
    assert first_command is not None and activate < first_command.start()
    assert re.search(r"^VENV\s*:=\s*\.venv$", (ROOT / "Makefile").read_text(), re.M)  # that one
    assert ".venv/bin/softplc" in readme[:first_command.start()]
