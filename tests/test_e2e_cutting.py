"""Issue 13 end to end: the daemon runs cutting_table.il on its simulated table (--speed max,
loopback Modbus); `softplc.cutting.client` streams worked examples; the trace is checked
against the ideal shapes (torch-on samples within chord tolerance + 1 um, end point within
1 um, no missed segment) and two runs give identical traces."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest
from daemon_util import ROOT, Daemon

from softplc.cutting import load_piece
from softplc.cutting.client import CutClient, trace_deviation

IL = ROOT / "ladder_programs" / "cutting_table.il"
PIECES = ROOT / "ladder_programs" / "pieces"
START_MM = 1.0  # both axes start 1 mm from their min switch: homing takes 3.4 s
COUNTS_PER_MM = 100_000.0
UM = 1e-3


@pytest.fixture
def table(tmp_path):
    """Start a daemon on the cutting table; yields a function giving (daemon, trace)."""
    text = (ROOT / "ladder_programs" / "cutting_table.toml").read_text(encoding="utf-8")
    cfg = tomllib.loads(text)
    start = START_MM * COUNTS_PER_MM
    text = text.replace(f"start = {cfg['devices']['X']['start']}", f"start = {start}")
    text = text.replace(f"start = {cfg['devices']['Y']['start']}", f"start = {start}")
    machine = tmp_path / "machine.toml"
    machine.write_text(text, encoding="utf-8")
    started: list[Daemon] = []

    def start_daemon(name: str = "trace") -> tuple[Daemon, Path]:
        trace = tmp_path / f"{name}.csv"
        d = Daemon(tmp_path, "--config", str(machine), "--speed", "max", "--trace",
                   str(trace), "--stats-interval", "0", program=IL)
        started.append(d)
        return d, trace

    yield start_daemon
    for d in started:
        d.kill()


def cut(daemon: Daemon, trace: Path, piece_file: str, **options: float):
    piece = load_piece(PIECES / piece_file, **options)
    with CutClient("127.0.0.1", daemon.port, progress=None) as client:
        res = client.stream(piece)
        frames = client.frames_sent
    assert daemon.stop() == 0  # the trace is complete once the daemon has closed it
    start = START_MM * COUNTS_PER_MM
    origin = (start + res.origin_counts[0], start + res.origin_counts[1])
    return piece, res, frames, trace_deviation(piece, trace, origin, COUNTS_PER_MM)


def check_run(piece, res, frames, rep) -> None:
    total = len(piece.segments())
    assert not res.interrupted and res.last_number == total and res.done == total
    assert frames == total  # no segment missed or repeated (it starts at the origin)
    assert rep.samples > 1000
    assert rep.worst <= piece.tolerance + UM
    assert math.dist(rep.end, piece.end) <= UM
    for origin in res.origin_counts:  # homing through the daemon: zero at the switch stop,
        # 30 mm retract: the work origin's true distance from the min trip point (E8)
        assert 29.47 <= (START_MM * COUNTS_PER_MM + origin) / COUNTS_PER_MM <= 29.505


def test_e3_rounded_rectangle_follows_the_ideal_shape(table):
    daemon, trace = table()
    check_run(*cut(daemon, trace, "achaflanado.toml", speed=10.0, move_speed=10.0))


def test_e2_escudo_twice_the_same_path(table):
    """E2 follows the ideal shape (check_run), twice. Through the daemon the host's frames
    land at whatever scan they reach the PLC, so the traces' times differ; the path does
    not: same end, same deviation. (Bit-identical runs on the virtual clock:
    test_cutting_table.py.)"""
    reports = []
    for name in ("a", "b"):
        daemon, trace = table(name)
        run = cut(daemon, trace, "escudo.toml", speed=10.0, move_speed=10.0)
        check_run(*run)
        reports.append(run[3])
    a, b = reports
    assert math.dist(a.end, b.end) <= 0.1 * UM
    assert a.worst == pytest.approx(b.worst, abs=1e-4)


class InterruptedClient(CutClient):
    """Ctrl-C while segment `at` is moving (raised from a poll, as the signal would)."""

    at = 3
    fired = False

    def read_state(self):
        s = super().read_state()
        if not self.fired and s.ejecutando and s.seg_done == self.at - 1:
            self.fired = True
            raise KeyboardInterrupt
        return s


def test_ctrl_c_stops_with_the_torch_off_and_the_piece_resumes(table):
    daemon, trace = table()
    piece = load_piece(PIECES / "escudo.toml", speed=10.0, move_speed=10.0)
    with InterruptedClient("127.0.0.1", daemon.port, progress=None) as client:
        res = client.stream(piece)
        assert res.interrupted and res.next_number == 3 and res.last_number == 2
        p3 = piece.segments()[2]
        assert math.dist(res.pos_mm, p3.start) > 0.01  # stopped inside segment 3
        state = client.read_state()
        assert state.seg_done == 2 and not state.ejecutando and state.fault == 0
        res2 = client.stream(piece, start_at=res.next_number)
    assert not res2.interrupted and res2.last_number == len(piece.segments())
    assert daemon.stop() == 0
    start = START_MM * COUNTS_PER_MM
    origin = (start + res2.origin_counts[0], start + res2.origin_counts[1])
    rep = trace_deviation(piece, trace, origin, COUNTS_PER_MM)
    assert rep.worst <= piece.tolerance + UM  # the torch was off back to segment 3's start
    assert math.dist(rep.end, piece.end) <= UM
