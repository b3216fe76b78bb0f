"""Issue 4 end to end: the daemon runs the drawing-table program with its simulated table
(`--speed max`, virtual clock), `softplc draw` streams G-code to it over Modbus TCP on
loopback, and the recorded trace is compared with the programmed path."""

from __future__ import annotations

from pathlib import Path

import pytest
from daemon_util import ROOT, Daemon
from modbus_util import refused_port
from zygote import default_sigint

from softplc.cli import main as softplc
from softplc.machines.drawing import max_deviation
from softplc.machines.drawing.deviation import load_trace
from softplc.machines.gcode import parse_file

SAMPLES = ROOT / "ladder_programs" / "samples"
CONFIG = ROOT / "ladder_programs" / "drawing_table.toml"


@pytest.fixture
def table(tmp_path):
    """Start a daemon with a program; yields (daemon, trace path)."""
    started: list[Daemon] = []

    def start(program: str) -> tuple[Daemon, Path]:
        trace = tmp_path / f"{program}.csv"
        d = Daemon(tmp_path, "--config", str(CONFIG), "--speed", "max", "--trace",
                   str(trace), "--stats-interval", "0", program=ROOT / "ladder_programs" /
                   program)
        started.append(d)
        return d, trace

    yield start
    for d in started:
        d.kill()


def draw(port: int, gcode: Path, trace: Path, *extra: str) -> int:
    return softplc(["draw", str(gcode), "--port", str(port), "--no-progress", "--poll",
                    "0.01", "--trace", str(trace), "--trace-wait", "10", *extra])


# The figure of `--plot` is drawn for one sample (the star: lines and travel): the same
# code for each, about 1 CPU-s a figure.
@pytest.mark.parametrize("sample", ["square.gcode", "circle.gcode", "star.gcode"])
def test_corrected_program_draws_within_one_step(table, sample, capsys, tmp_path):
    d, trace = table("drawing_table.il")
    plot = tmp_path / "drawn.png"
    figure = ("--plot", str(plot)) if sample == "star.gcode" else ()
    assert draw(d.port, SAMPLES / sample, trace, *figure) == 0
    assert d.stop() == 0  # SIGINT: clean shutdown flushes the whole trace
    rows = load_trace(trace)
    prog = parse_file(SAMPLES / sample)
    dev = max_deviation(prog.steps(), rows)
    # Arcs are linearised within the chord tolerance, so within 1 step of the chords is
    # within chord tolerance + 1 step of the arcs.
    assert dev.samples > 100
    assert dev.max_steps <= 1.0, dev
    assert dev.missed_steps == 0
    assert plot.stat().st_size > 10_000 if figure else not plot.exists()
    # homing comes first: the axes reach home (0, 0) before anything is drawn
    first_down = next(i for i, r in enumerate(rows) if r[3])
    assert any(r[1] == 0 and r[2] == 0 for r in rows[:first_down])
    assert rows[0][1] > 0 and rows[0][2] > 0  # started away from home
    assert "max deviation" in capsys.readouterr().out


def test_seed_program_shows_its_documented_failures(table, tmp_path):
    """The seed program (a faithful rebuild, defects included) cannot draw the star: Z is
    driven by X alone with `Z := A_B * B`, so the drawing leaves the programmed lines. The
    star's first two edges (the vertical one, DX = 0, and a steep one) show it; the return
    home at the end lets `draw` find the end of the run in the trace at once."""
    d, trace = table("drawing_table_seed.il")
    keep = ("G18", "N10 ", "N20 ", "N30 ", "N40 ", "N130 ", "N140 ")
    edges = tmp_path / "star-edges.gcode"
    edges.write_text("".join(ln for ln in (SAMPLES / "star.gcode").open()
                             if ln.startswith(keep)))
    # the seed's EJECUTANDO flickers to 0 between steps: the host races through points
    assert draw(d.port, edges, trace, "--move-timeout", "30") in (0, 1)
    assert d.stop() == 0
    dev = max_deviation(parse_file(edges).steps(), load_trace(trace))
    assert dev.max_steps > 100, dev


def test_bad_gcode_is_refused_before_anything_is_sent(table, tmp_path, capsys):
    d, trace = table("drawing_table.il")
    bad = tmp_path / "bad.gcode"
    bad.write_text("G01 X1 Z1 Y1\nG01 X30 Z1\nG01 XA Z2\n")
    assert softplc(["draw", str(bad), "--port", str(d.port), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "bad.gcode:2" in err and "bad.gcode:3" in err
    assert d.client().read_registers(3, 1) == [0]  # nothing was written


def test_unreachable_daemon_is_a_clear_error(tmp_path, capsys):
    with refused_port() as port:  # nobody listening, and no parallel worker takes it
        rc = softplc(["draw", str(SAMPLES / "square.gcode"), "--port", str(port),
                      "--no-progress", "--retries", "0", "--request-timeout", "0.5"])
    assert rc == 1
    err = capsys.readouterr().err
    assert f"127.0.0.1:{port}" in err and "Traceback" not in err


def test_ctrl_c_lifts_the_pen_and_the_drawing_resumes(table, tmp_path):
    """Ctrl-C in `softplc draw` stops after the current segment with the pen up and says
    where to resume; `--start-at` finishes the drawing as if never interrupted."""
    import os
    import re
    import signal
    import subprocess
    import sys
    import time

    d, trace = table("drawing_table.il")
    gcode = SAMPLES / "circle.gcode"
    cmd = [sys.executable, "-m", "softplc", "draw", str(gcode), "--port", str(d.port),
           "--poll", "0.01"]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, env=env, preexec_fn=default_sigint)
    seen = b""
    deadline = time.monotonic() + 30
    # interrupt as the first segment starts (the progress line "0/N", written at once
    # off a terminal too): whatever the machine's speed, the drawing (4 s of moves) has
    # not ended then; the wait is on the host's own output, never on a time
    while b"] 0/" not in seen and time.monotonic() < deadline:
        chunk = os.read(proc.stderr.fileno(), 4096)
        if not chunk:
            break
        seen += chunk
    proc.send_signal(signal.SIGINT)
    _, rest = proc.communicate(timeout=30)
    err = (seen + rest).decode(errors="replace")
    assert proc.returncode == 130, err
    m = re.search(r"resume with --start-at (\d+)", err)
    assert m, err
    with d.client() as c:
        assert c.read_registers(5, 1) == [0]  # the last frame lifted the pen
    rc = softplc(["draw", str(gcode), "--port", str(d.port), "--no-progress", "--poll",
                  "0.01", "--start-at", m[1]])
    assert rc == 0
    assert d.stop() == 0
    rows = load_trace(trace)
    dev = max_deviation(parse_file(gcode).steps(), rows)
    assert dev.max_steps <= 1.0 and dev.missed_steps == 0, dev
