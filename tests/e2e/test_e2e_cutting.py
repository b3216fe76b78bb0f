"""Issue 13 end to end: the daemon runs cutting_table.il on its simulated table (--speed max,
loopback Modbus); `softplc.machines.cutting.client` streams worked examples; the trace is checked
against the ideal shapes (torch-on samples within chord tolerance + 1 um, end point within
1 um, no missed segment) and two runs give byte-identical traces (the program's host_wait
bit holds the virtual clock while it waits for the host). E8 (homing) and E9 (limit stop)
through the daemon too; E9 forces the switch input through the web monitor's API."""

from __future__ import annotations

import csv
import json
import math
import re
import threading
import time
import tomllib
import urllib.request
from pathlib import Path

import pytest
from daemon_util import ROOT, Daemon
from waits import WAIT_S, until

from softplc.commands.io import Client
from softplc.errors import HostError
from softplc.machines.cutting import Piece, load_piece
from softplc.machines.cutting.client import CutClient, CutResult, TraceReport, trace_deviation
from softplc.machines.cutting.regmap import SegmentWords

IL = ROOT / "ladder_programs" / "cutting_table.il"
PIECES = ROOT / "ladder_programs" / "pieces"
START_MM = 1.0  # both axes start 1 mm from their min switch: homing takes 3.4 s
COUNTS_PER_MM = 100_000.0
UM = 1e-3
SCAN_S = 0.001  # the cutting table's scan period (ladder_programs/cutting_table.toml)


@pytest.fixture
def table(tmp_path):
    """Start a daemon on the cutting table; yields a function giving (daemon, trace).
    `start_mm=None` keeps the machine's own start (E8: X 123.4, Y 57.0 mm)."""
    text = (ROOT / "ladder_programs" / "cutting_table.toml").read_text(encoding="utf-8")
    cfg = tomllib.loads(text)
    started: list[Daemon] = []

    def start_daemon(name: str = "trace", *args: str,
                     start_mm: float | None = START_MM) -> tuple[Daemon, Path]:
        machine = tmp_path / "machine.toml"
        new = text
        if start_mm is not None:
            for axis in "XY":
                new = new.replace(f"start = {cfg['devices'][axis]['start']}",
                                  f"start = {start_mm * COUNTS_PER_MM}")
        machine.write_text(new, encoding="utf-8")
        trace = tmp_path / f"{name}.csv"
        d = Daemon(tmp_path, "--config", str(machine), "--speed", "max", "--trace",
                   str(trace), "--stats-interval", "0", *args, program=IL)
        started.append(d)
        return d, trace

    yield start_daemon
    for d in started:
        d.kill()


def cut(daemon: Daemon, trace: Path, piece_file: str, poll: float = 0.01,
        **options: float):
    piece = load_piece(PIECES / piece_file, **options)
    with CutClient("127.0.0.1", daemon.port, progress=None, poll_interval=poll) as client:
        res = client.stream(piece)
        frames = client.frames_sent
    # the daemon flushes the trace when the clock stops to wait for the host: the file is
    # complete while the daemon still runs (`softplc cut --trace` reads it then)
    end, size = time.monotonic() + WAIT_S, -1
    while trace.stat().st_size != size:
        assert time.monotonic() < end
        size = trace.stat().st_size
        time.sleep(0.1)
    running = trace.read_bytes()
    assert daemon.stop() == 0
    assert trace.read_bytes() == running
    return piece, res, frames, deviation(piece, trace, res)


def deviation(piece: Piece, trace: Path, res: CutResult) -> TraceReport:
    """The trace against the ideal piece, in the work frame the host homed to (`res`)."""
    start = START_MM * COUNTS_PER_MM
    origin = (start + res.origin_counts[0], start + res.origin_counts[1])
    return trace_deviation(piece, trace, origin, COUNTS_PER_MM)


def assert_follows_the_piece(piece: Piece, rep: TraceReport) -> None:
    assert rep.worst <= piece.tolerance + UM
    assert math.dist(rep.end, piece.end) <= UM


def check_run(piece, res, frames, rep) -> None:
    total = len(piece.segments())
    assert not res.interrupted and res.last_number == total and res.done == total
    assert frames == total  # no segment missed or repeated (it starts at the origin)
    assert rep.samples > 1000
    assert_follows_the_piece(piece, rep)
    for origin in res.origin_counts:  # homing through the daemon: zero at the switch stop,
        # 30 mm retract: the work origin's true distance from the min trip point (E8)
        assert 29.47 <= (START_MM * COUNTS_PER_MM + origin) / COUNTS_PER_MM <= 29.50


def test_e3_rounded_rectangle_follows_the_ideal_shape(table):
    daemon, trace = table()
    check_run(*cut(daemon, trace, "achaflanado.toml", speed=10.0, move_speed=10.0))


def test_e2_escudo_twice_byte_identical_traces(table):
    """E2 follows the ideal shape (check_run), twice, with different host poll periods:
    the traces are byte-identical. The host's frames reach the PLC at different wall
    times, but while the program waits for its host (READY, nothing queued: %M118, the
    config's [daemon] host_wait) the daemon runs no scan, so each frame lands at the
    same PLC time; a frame written earlier waits in the PLC's queue."""
    traces = []
    for name, poll in (("a", 0.001), ("b", 0.02)):
        daemon, trace = table(name)
        check_run(*cut(daemon, trace, "escudo.toml", poll, speed=10.0, move_speed=10.0))
        traces.append(trace.read_bytes())
    assert len(traces[0]) > 10_000 and traces[0] == traces[1]


@pytest.mark.parametrize("piece_file", ["polinomio.toml", "arandela.toml"])
def test_e5_newton_curve_and_e10_washer_follow_the_ideal_shape(table, piece_file):
    """E5: 60 chords of the FIGURA 20 polynomial (non-equidistant nodes); E10: two full
    circles of 55 and 87 chords with a move between them. Every chord is a segment that
    stops at its end (the machine has no blending), queued while the previous one runs."""
    daemon, trace = table()
    check_run(*cut(daemon, trace, piece_file, speed=10.0, move_speed=10.0))


def trace_rows(trace: Path) -> list[tuple[float, float, float, int]]:
    """(t s, x mm, y mm, torch) of a trace CSV: true positions from the min trip points."""
    with open(trace, newline="") as f:
        return [(float(r["t"]), float(r["x"]) / COUNTS_PER_MM, float(r["z"]) / COUNTS_PER_MM,
                 int(r["pen"])) for r in csv.DictReader(f)]


def settled_at(rows: list, i: int, window: float) -> float:
    """The time from which coordinate `i` stays within `window` mm of its last value."""
    final = rows[-1][i]
    t = rows[0][0]
    for r in rows:
        if abs(r[i] - final) > window:
            t = None
        elif t is None:
            t = r[0]
    return t


def web_post(port: int, path: str, body: dict) -> dict:
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", json.dumps(body).encode(),
                                 {"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=WAIT_S) as r:
        return json.loads(r.read())


def unforce(port: int, obj: str) -> None:
    """Release a forced input through the web monitor on `port` and wait until the daemon
    applied it (at a scan boundary: that scan reads the input), not a fixed time."""
    web_post(port, "/api/unforce", {"object": obj})
    status = Client("127.0.0.1", port).status
    until(lambda: obj not in status()["forced"])


def test_e8_homing_and_e9_limit_stop_through_the_daemon(table):
    """E8 from the machine's start (X 123.4, Y 57.0 mm from the min trip points): both
    axes search at once, stop, zero, retract 30 mm; Y is home at about 8.95 s, X and
    HOMED at 15.59 s (+-0.05 s); the host reads (0, 0) +-1 um; each axis rests 29.47-29.50
    mm from its trip point (the stop ramp is v^2/2a = 0.5 mm).
    E9: then cutting along X at 20 mm/s, the X max switch input is forced made (through
    the web monitor, as TwidoSuite forces an input): fault 1 in that scan, torch off, X
    stops within v^2/2a = 2.0 mm (+ 2 scans, 0.04 mm) of where the torch went out, Y does
    not move; RESET is refused while the input is made and accepted once it is released."""
    daemon, trace = table("e8e9", "--web", "0", start_mm=None)
    web = daemon.web_port()
    with CutClient("127.0.0.1", daemon.port, progress=None, poll_interval=0.002) as client:
        homed = client.wait_for(lambda s: s.step == 4, WAIT_S, "homing")
        client.offer(SegmentWords(200_000, 0, 20.0, 1, 1), "a long cut along X")
        client.wait_for(lambda s: s.pos_um[0] >= 20_000, WAIT_S, "cruising")
        web_post(web, "/api/force", {"object": "%I0.9", "value": 1})
        state = client.poll(client.read_state, lambda s: s.step == 9, WAIT_S, "the fault")
        assert state.fault == 1
        client.write_bit(102, True)  # RESET, refused while the switch is made
        deadline = time.monotonic() + 0.3
        while time.monotonic() < deadline:
            s = client.read_state()
            assert s.step == 9 and s.fault == 1
        unforce(web, "%I0.9")
        client.write_bit(102, True)
        state = client.poll(client.read_state, lambda s: s.step == 4, WAIT_S, "READY after RESET")
        assert state.fault == 0 and state.ejecutando == 0
    assert daemon.stop() == 0
    rows = trace_rows(trace)
    lit = [i for i, r in enumerate(rows) if r[3]]

    # E8: the PLC clock stood still at READY until the segment came (the program waited
    # for its host), so the segment's first scan follows HOMED by one scan
    assert homed.fault == 0 and all(abs(p) <= 1 for p in homed.pos_um)
    t_homed = rows[lit[0]][0] - 0.001
    homing = [r for r in rows if r[0] <= t_homed]
    in_position = 16 * UM  # the axes' in-position band (Ixx28 = 1600 counts)
    assert settled_at(homing, 2, in_position) == pytest.approx(8.95, abs=0.05)
    t_x = settled_at(homing, 1, in_position)
    assert t_x == pytest.approx(15.59, abs=0.05) and t_x <= t_homed <= t_x + 0.05
    for axis in (1, 2):
        assert 29.47 <= homing[-1][axis] <= 29.50

    # E9
    off = lit[-1] + 1  # the first sample with the torch out: the fault scan
    assert rows[off][0] - rows[lit[0]][0] > 1.0  # it was cutting for a while
    stop = rows[-1][1] - rows[off][1]
    assert 1.9 <= stop <= 20.0 ** 2 / (2 * 100.0) + 2 * 0.001 * 20.0
    y = [r[2] for r in rows[lit[0]:]]
    assert max(y) - min(y) <= 0.5 * UM  # Y holds (the P-D loop's settling creep: 0.2 um)


class InterruptedClient(CutClient):
    """Ctrl-C while segment `at` is moving (raised from a poll, as the signal would)."""

    at = 3
    fired = 0  # the segment moving when Ctrl-C came (0: not yet)

    def read_state(self):
        s = super().read_state()
        # from segment `at` on: a poll that a loaded machine delays past segment 3's end
        # interrupts the next one, which tests the same thing
        if not self.fired and s.ejecutando and s.seg_done >= self.at - 1:
            self.fired = s.seg_done + 1
            raise KeyboardInterrupt
        return s


def test_ctrl_c_stops_with_the_torch_off_and_the_piece_resumes(table):
    daemon, trace = table()
    piece = load_piece(PIECES / "escudo.toml", speed=10.0, move_speed=10.0)
    with InterruptedClient("127.0.0.1", daemon.port, progress=None) as client:
        res = client.stream(piece)
        n = client.fired
        assert n >= 3 and res.interrupted and res.next_number == n and res.last_number == n - 1
        seg = piece.segments()[n - 1]
        # stopped inside segment n: off its start by at least about one scan's travel at
        # its speed (one scan is 0.01 mm here: a stop can land one scan after the start,
        # 0.00999... mm in floats, whatever the machine's speed) and short of its end
        assert math.dist(res.pos_mm, seg.start) >= 0.5 * seg.speed * SCAN_S
        assert math.dist(res.pos_mm, seg.end) > 0
        state = client.read_state()
        assert state.seg_done == n - 1 and not state.ejecutando and state.fault == 0
        res2 = client.stream(piece, start_at=res.next_number)
    assert not res2.interrupted and res2.last_number == len(piece.segments())
    assert daemon.stop() == 0
    # the torch was off back to segment n's start
    assert_follows_the_piece(piece, deviation(piece, trace, res2))


def force_when(web: int, port: int, obj: str, value: int, ready) -> threading.Thread:
    """Force `obj` through the web monitor once `ready(state)` (a second Modbus host
    polling the PLC, as an operator watching the table would)."""
    def watch() -> None:
        with CutClient("127.0.0.1", port, progress=None, poll_interval=0.002) as c:
            c.poll(c.read_state, ready, WAIT_S, "the moment to force")
            web_post(web, "/api/force", {"object": obj, "value": value})

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    return t


def test_softplc_cut_reports_the_faulted_segment_then_jog_reset_home(table, tmp_path,
                                                                      capsys):
    """Issue 23: `softplc cut` says which segment faulted and the --start-at that resumes
    it; `softplc cut reset` says why it is refused (the switch, and the jog that leaves
    it); `softplc cut jog` moves away from the made switch, not into it; once the switch
    is released, reset, then home, are accepted."""
    from softplc.cli import main

    piece = tmp_path / "long.toml"
    piece.write_text('speed = 10.0\n[[op]]\nkind = "move"\nto = [10, 10]\n'
                     '[[op]]\nkind = "line"\nto = [90, 10]\n[[op]]\nkind = "line"\n'
                     'to = [90, 20]\n', encoding="utf-8")
    daemon, _ = table("jog", "--web", "0")
    web = daemon.web_port()
    port = str(daemon.port)
    watcher = force_when(web, daemon.port, "%I0.9", 1,
                         lambda s: s.step == 5 and s.pos_um[0] > 20_000)
    assert main(["cut", str(piece), "--port", port]) == 3
    watcher.join(WAIT_S)
    out = capsys.readouterr().out
    assert "stopped by a fault: 1 segments" in out
    assert "fault 1 (limit switch) during segment 2/3 (op[1])" in out
    assert "resume with --start-at 2" in out
    assert main(["cut", "reset", "--port", port]) == 1
    err = capsys.readouterr().err
    assert "RESET refused" in err and "SensX_Max made (softplc cut jog X-)" in err
    assert main(["cut", "jog", "X+", "1", "--port", port]) == 1  # into the switch
    assert "SensX_Max is made; the PLC jogs only away from it" in capsys.readouterr().err
    assert main(["cut", "jog", "X-", "3", "--port", port]) == 0
    moved = float(re.search(r"moved (\S+) mm", capsys.readouterr().out)[1])
    assert moved >= 3.0
    unforce(web, "%I0.9")
    assert main(["cut", "reset", "--port", port]) == 0
    assert "RESET accepted: READY" in capsys.readouterr().out
    assert main(["cut", "home", "--port", port]) == 0
    assert "homed: READY at (0.000, 0.000) mm" in capsys.readouterr().out
    assert main(["cut", "jog", "X-", "--port", port]) == 1  # READY: no jog
    assert "jog works in FAULT only" in capsys.readouterr().err
    assert main(["cut", "reset", "--port", port]) == 1
    assert "nothing to reset" in capsys.readouterr().err
    assert daemon.stop() == 0


def test_a_fault_mid_piece_resumes_after_reset_from_the_faulted_segment(table):
    """The fault's CutResult names the segment that was running; after RESET the frame
    the host had queued is not cut (refused, issue 23); resuming from it cuts the rest,
    with the torch off back to that segment's start."""
    daemon, trace = table("estop", "--web", "0")
    web = daemon.web_port()
    piece = load_piece(PIECES / "escudo.toml", speed=10.0, move_speed=10.0)
    watcher = force_when(web, daemon.port, "%I0.16", 0,  # the E-stop pressed from segment 3
                         lambda s: s.seg_done >= 2 and s.step == 5)  # (a late poll: 4, 5...)
    with CutClient("127.0.0.1", daemon.port, progress=None) as client:
        res = client.stream(piece)
        watcher.join(WAIT_S)
        assert res.fault == 5 and not res.interrupted
        n = res.next_number
        assert 3 <= n <= 8 and res.last_number == n - 1
        assert res.fault_where == piece.segments()[n - 1].where
        with pytest.raises(HostError, match="E-stop pressed"):
            client.reset()
        unforce(web, "%I0.16")
        state = client.reset()
        assert state.step == 4 and state.seg_done == n - 1 and not state.ejecutando
        res2 = client.stream(piece, start_at=res.next_number)
    assert not res2.fault and res2.last_number == len(piece.segments())
    assert daemon.stop() == 0
    assert_follows_the_piece(piece, deviation(piece, trace, res2))
