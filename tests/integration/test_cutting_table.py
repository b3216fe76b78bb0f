"""The cutting table's PLC program (ladder_programs/cutting_table.il) on its machine, through
the PLC API on the virtual clock: homing (E8), the segment handshake, the line split in float
IL, the torch, the work-area check, limit switch and E-stop stops (E9), RESET."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest
from warm import simulated, warm

from softplc.machines.cutting.regmap import (
    EJECUTANDO,
    FAULT,
    INICIO,
    SEG_DONE,
    SEG_KIND,
    SEG_NO,
    SEG_V,
    SEG_X,
    SEG_Y,
    STATE,
)
from softplc.plc import PLC

ROOT = Path(__file__).resolve().parents[2]
IL = ROOT / "ladder_programs" / "cutting_table.il"
TOML = ROOT / "ladder_programs" / "cutting_table.toml"
COUNTS_PER_MM = 100_000.0
READY, MOVING, FAULT_STEP = 4, 5, 9


def machine(start_mm: tuple[float, float] | None = None) -> PLC:
    cfg = tomllib.loads(TOML.read_text(encoding="utf-8"))
    if start_mm is not None:
        cfg["devices"]["X"]["start"] = start_mm[0] * COUNTS_PER_MM
        cfg["devices"]["Y"]["start"] = start_mm[1] * COUNTS_PER_MM
    return PLC.from_file(IL, cfg)


def home(plc: PLC) -> None:
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == READY, timeout=20)


def homed(start_mm: tuple[float, float] = (1.0, 1.0)) -> PLC:
    """A machine started at `start_mm` and homed: restored to the state its homing reached
    in this process (tests/warm.py; test_two_runs_... checks it runs on the same)."""
    return warm(("cutting_table", start_mm), lambda: machine(start_mm), home)


def true_mm(plc: PLC) -> tuple[float, float]:
    return (plc.devices["X"].position / COUNTS_PER_MM, plc.devices["Y"].position / COUNTS_PER_MM)


def offer(plc: PLC, x_um: int, y_um: int, v: float, kind: int = 1, number: int = 1) -> None:
    plc[f"%MD{SEG_X}"] = x_um
    plc[f"%MD{SEG_Y}"] = y_um
    plc[f"%MF{SEG_V}"] = v
    plc[f"%MW{SEG_KIND}"] = kind
    plc[f"%MW{SEG_NO}"] = number
    plc[f"%MW{INICIO}"] = 1


def test_e8_homing_both_axes_at_once_with_the_30_mm_retract():
    plc = machine()  # E8: X 123.4 mm, Y 57.0 mm from the min trip points
    y_done = None
    while plc.time < 20 and plc[f"%MW{STATE}"] != READY:
        plc.scan()
        if y_done is None and plc["%M33"] and plc["%MW248:X3"] and plc["%MW248:X2"]:
            y_done = plc.time
    assert plc[f"%MW{STATE}"] == READY and plc["%M110"]
    assert plc.time == pytest.approx(15.59, abs=0.05)
    assert y_done == pytest.approx(8.95, abs=0.05)
    assert plc[f"%MD{112}"] == pytest.approx(0, abs=1) and plc["%MD114"] == pytest.approx(0, abs=1)
    for axis in true_mm(plc):  # the stop after the trip (spec: 0.50-0.53 mm), then 30 mm back
        assert 29.47 <= axis <= 29.50  # stop v^2/2a = 0.5 mm after the trip (+ reaction)
    assert plc[f"%MW{FAULT}"] == 0


def test_homing_with_an_axis_starting_on_its_min_switch():
    plc = homed((1.0, -0.2))  # Y starts with its min switch made: zero where it stands
    assert plc[f"%MW{FAULT}"] == 0
    assert 29.47 <= true_mm(plc)[0] <= 29.50
    assert true_mm(plc)[1] == pytest.approx(29.8, abs=1e-3)


def test_broken_min_switch_fails_homing_at_the_timeout():
    """The %TM0 timeout (36 s in the machine) shortened to 2 s here to keep the suite
    quick; the rubber stop removed so that nothing else stops the search."""
    cfg = tomllib.loads(TOML.read_text(encoding="utf-8"))
    cfg["devices"]["SensX_Min"]["fault"] = "stuck_open"
    del cfg["devices"]["X"]["geometry"]["hard_stop_minus"]
    assert cfg["timers"]["%TM0"]["preset"] == 360  # 100 ms base: 36 s
    cfg["timers"]["%TM0"]["preset"] = 20
    plc = PLC.from_file(IL, cfg)
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == FAULT_STEP, timeout=5)
    assert plc[f"%MW{FAULT}"] == 2
    assert plc.time == pytest.approx(2.0, abs=0.11)


def test_a_cut_line_splits_speed_and_acceleration_so_the_path_stays_straight():
    plc = homed()
    x0 = true_mm(plc)
    offer(plc, 80_000, 60_000, 50.0)  # E7: (0,0)->(80,60), corrected split
    plc.scan()
    # the handshake: taken in one scan
    assert plc[f"%MW{INICIO}"] == 0 and plc[f"%MW{EJECUTANDO}"] == 1
    assert plc[f"%MW{STATE}"] == MOVING and plc["%Q0.2"]
    assert plc["%MF116"] == pytest.approx(40.0, rel=1e-6)
    assert plc["%MF118"] == pytest.approx(30.0, rel=1e-6)
    worst = 0.0
    t0 = plc.time
    while plc[f"%MW{EJECUTANDO}"]:
        plc.scan()
        x, y = true_mm(plc)
        dx, dy = x - x0[0], y - x0[1]
        worst = max(worst, abs(dx * 0.6 - dy * 0.8))  # distance from the line
    assert worst < 1e-4
    assert plc.time - t0 == pytest.approx(100 / 50 + 50 / 100, abs=0.02)
    assert plc[f"%MW{SEG_DONE}"] == 1 and not plc["%Q0.2"]
    assert plc["%MD112"] == pytest.approx(80_000, abs=1)
    assert plc["%MD114"] == pytest.approx(60_000, abs=1)


def test_a_move_segment_keeps_the_torch_off():
    plc = homed()
    offer(plc, 5_000, 0, 10.0, kind=2)
    lit = False
    for _ in range(2000):
        plc.scan()
        lit |= plc["%Q0.2"] or plc.devices["torch"].lit
        if not plc[f"%MW{EJECUTANDO}"]:
            break
    assert not lit and plc["%MD112"] == pytest.approx(5000, abs=1)


@pytest.mark.parametrize("x_um,y_um", [(240_001, 0), (0, -1)])
def test_a_target_outside_the_work_area_is_refused(x_um, y_um):
    plc = homed()
    before = true_mm(plc)
    offer(plc, x_um, y_um, 10.0)
    plc.run(0.2)
    assert plc[f"%MW{FAULT}"] == 3 and plc[f"%MW{STATE}"] == FAULT_STEP
    assert true_mm(plc) == pytest.approx(before, abs=1e-3)  # settling only


def test_e9_limit_switch_stops_both_axes_torch_off_reset_refused_while_made():
    plc = homed()
    offer(plc, 200_000, 0, 20.0)
    plc.run(2.0)  # cruising along X at 20 mm/s
    y0 = true_mm(plc)[1]
    plc.devices["SensX_Max"].set_fault("stuck_closed")
    x_trip = true_mm(plc)[0]
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == FAULT_STEP, timeout=0.01)
    assert not plc["%Q0.2"] and plc[f"%MW{FAULT}"] == 1
    plc.run(1.0)
    stop = true_mm(plc)[0] - x_trip
    assert 0 < stop <= 20.0 ** 2 / (2 * 100.0) + 2 * 0.001 * 20.0 + 1e-6
    assert true_mm(plc)[1] == y0
    plc["%M102"] = 1  # RESET refused while the switch is made
    plc.run(0.01)
    assert plc[f"%MW{STATE}"] == FAULT_STEP and plc[f"%MW{FAULT}"] == 1
    plc.devices["SensX_Max"].set_fault("none")
    plc.scan()  # the input follows at the next device update
    plc["%M102"] = 1
    plc.run(0.01)
    assert plc[f"%MW{STATE}"] == READY and plc[f"%MW{FAULT}"] == 0
    assert plc[f"%MW{EJECUTANDO}"] == 0


def test_a_max_switch_reached_for_real_stops_x_under_control_and_x_holds_there():
    """The X max switch moved to 100 mm (true position), inside the work area, reached while
    cutting at 20 mm/s: the controller's limit input stops X at limit_decel (100 mm/s^2:
    2 mm past the trip point, + 1 scan), the loop stays closed and holds (it used to end in
    a fatal following error, the axis drifting backwards); fault 1; X jogs away only."""
    cfg = tomllib.loads(TOML.read_text(encoding="utf-8"))
    cfg["devices"]["X"]["geometry"]["limit_plus"] = 100.0 * COUNTS_PER_MM
    for axis in ("X", "Y"):
        cfg["devices"][axis]["start"] = COUNTS_PER_MM
    plc = PLC.from_file(IL, cfg)
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == READY, timeout=20)
    offer(plc, 150_000, 0, 20.0)  # user 150 mm = true 179.5 mm: through the switch
    assert plc.run_until(lambda p: p.devices["SensX_Max"].made, timeout=10)
    plc.run(1.0)
    x = plc.devices["X"]
    assert 0 < true_mm(plc)[0] - 100.0 <= 20.0 ** 2 / (2 * 100.0) + 0.001 * 20.0 + 1e-6
    assert plc[f"%MW{STATE}"] == FAULT_STEP and plc[f"%MW{FAULT}"] == 1
    assert x.closed and x.error == 3 and x.fe_max < 0.01 * COUNTS_PER_MM  # Err.LIMIT
    held = true_mm(plc)[0]
    plc.run(3.0)
    assert abs(true_mm(plc)[0] - held) < 1e-5  # held to 10 nm (it drifted 0.06 mm/s)
    plc["%M104"] = 1  # jog X+ in FAULT: not into the made switch
    plc.run(0.5)
    assert abs(true_mm(plc)[0] - held) < 1e-5
    plc["%M104"], plc["%M105"] = 0, 1  # jog X-: away from it
    plc.run(0.5)
    assert true_mm(plc)[0] < held - 2.0 and not plc.devices["SensX_Max"].made


def test_estop_stops_and_latches_fault_5():
    plc = homed()
    offer(plc, 50_000, 50_000, 10.0)
    plc.run(1.0)
    plc.devices["estop"].press()
    plc.run(0.5)
    assert plc[f"%MW{FAULT}"] == 5 and not plc["%Q0.2"]
    assert math.isclose(plc.devices["X"].v, 0.0, abs_tol=1e-6)
    plc["%M102"] = 1
    plc.run(0.01)
    assert plc[f"%MW{STATE}"] == FAULT_STEP  # still pressed
    plc.devices["estop"].release()
    plc.scan()
    plc["%M102"] = 1
    plc.run(0.01)
    assert plc[f"%MW{STATE}"] == READY


def run_piece(plc: PLC, piece_file: str) -> list[tuple]:
    """Feed a piece's segment frames through the words, as the Modbus host does; the trace."""
    from softplc.machines.cutting import load_piece
    from softplc.machines.cutting.client import feed_plc

    piece = load_piece(ROOT / "ladder_programs" / "pieces" / piece_file, speed=10.0,
                       move_speed=10.0)
    assert feed_plc(plc, piece, timeout=30) == len(piece.segments())
    return list(plc.devices["trace"].samples)


def test_two_runs_on_the_virtual_clock_give_identical_traces():
    """Homed and cut twice, one machine homed here, the other restored to the homed state
    of an earlier homing (what the other tests start from): the same trace, homing
    included, and the same memory and devices after it."""
    fresh = machine((1.0, 1.0))
    home(fresh)
    restored = homed()
    a, b = run_piece(fresh, "escudo.toml"), run_piece(restored, "escudo.toml")
    assert len(a) > 1000 and a == b
    assert simulated(fresh) == simulated(restored)


def test_hold_while_moving_stops_now_torch_off_and_the_next_segment_starts_there():
    plc = homed()
    offer(plc, 100_000, 0, 20.0, number=7)
    plc.run(1.0)
    plc["%M101"] = 1  # HOLD (the host's Ctrl-C)
    assert plc.run_until(lambda p: p[f"%MW{EJECUTANDO}"] == 0, timeout=2)
    assert not plc["%Q0.2"] and plc[f"%MW{SEG_DONE}"] != 7
    assert 10_000 < plc["%MD112"] < 100_000
    plc["%M101"] = 0
    offer(plc, 5_000, 0, 20.0, number=8)
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 8, timeout=10)
    assert plc["%MD112"] == pytest.approx(5_000, abs=1)


def test_seed_mode_streamed_the_machine_cuts_the_thesis_defects():
    """The thesis's path for E5 (seed mode: h = x1 - x0 on unequal nodes, B12; sampling
    stops at x_{n-1}, B16) fed to the PLC like the corrected one: the machine follows it
    faithfully, so its trace shows the defects against the ideal curve (the corrected run:
    test_e2e_cutting.py, within 0.0045 mm)."""
    import numpy as np

    from softplc.machines.cutting import load_piece
    from softplc.machines.cutting.client import feed_plc

    piece = load_piece(ROOT / "ladder_programs" / "pieces" / "polinomio.toml", speed=10.0,
                       move_speed=10.0)
    plc = homed()
    assert feed_plc(plc, piece, timeout=30, seed=True) == len(piece.segments(seed=True))
    origin = [plc.devices[a].position - plc[f"%MD{d}"] / 1000.0 * COUNTS_PER_MM
              for a, d in (("X", 112), ("Y", 114))]  # true counts of the work origin
    rows = [(s[1], s[2], s[3]) for s in plc.devices["trace"].samples]
    x = (np.array([r[0] for r in rows]) - origin[0]) / COUNTS_PER_MM
    y = (np.array([r[1] for r in rows]) - origin[1]) / COUNTS_PER_MM
    lit = np.array([r[2] == 1 for r in rows])
    worst = piece.deviations(x[lit], y[lit]).max()
    assert worst > 2.0  # the thesis's curve leaves the ideal one by 2 mm and more
    assert (x[-1], y[-1]) == (pytest.approx(60.0, abs=1e-3), pytest.approx(199 / 9, abs=1e-3))
    assert piece.end == (90.0, 5.0)  # where the corrected curve ends


def test_the_torch_stays_lit_from_cut_to_cut_and_goes_out_for_a_move():
    """E2: a move, then seven cut segments in a row: one ignition (the queued cut starts in
    the scan after the previous one ends, the torch bridges that scan), out at the end."""
    samples = run_piece(homed(), "escudo.toml")
    pen = [s[3] for s in samples]
    first = pen.index(1)
    last = len(pen) - 1 - pen[::-1].index(1)
    assert all(pen[first:last + 1])  # never out between the cuts
    assert not any(pen[:first]) and samples[first][0] > 0.5  # off during the move


@pytest.mark.parametrize("kind,lit", [(1, False), (3, True)])
def test_the_hosts_look_ahead_keeps_the_torch_lit_when_the_next_frame_is_late(kind, lit):
    """A cut ends before the host has written the next one (the PLC in READY, nothing
    queued: the daemon's host_wait holds the clock there). Kind 1 gives no look-ahead, so
    the torch goes out for that scan; kind 3 ("a cut follows": regmap.piece_words) keeps
    it lit whatever the host's timing, as when the next cut was already queued. This was
    the cause of test_e2_escudo_twice_byte_identical_traces failing on fast machines."""
    plc = homed()
    offer(plc, 2_000, 0, 10.0, kind=kind, number=1)
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 1, timeout=5)
    assert plc[f"%MW{STATE}"] == READY and plc["%Q0.2"] == lit
    offer(plc, 2_000, 2_000, 10.0, kind=1, number=2)  # the late frame
    plc.scan()
    assert plc[f"%MW{STATE}"] == MOVING and plc["%Q0.2"]
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 2, timeout=5)
    assert not plc["%Q0.2"]


def test_a_chained_cut_whose_next_frame_does_not_come_puts_the_torch_out():
    """The look-ahead bridges one scan only: a host that then sends nothing (real time,
    no host_wait) does not leave the torch burning in one spot."""
    plc = homed()
    offer(plc, 2_000, 0, 10.0, kind=3, number=1)
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 1, timeout=5)
    assert plc["%Q0.2"]
    plc.scan()
    assert plc[f"%MW{STATE}"] == READY and not plc["%Q0.2"]


@pytest.mark.parametrize("kind", [0, 4, 7])
def test_a_segment_of_an_unknown_kind_is_fault_6(kind):
    plc = homed()
    offer(plc, 2_000, 0, 10.0, kind=kind)
    plc.run(0.05)
    assert plc[f"%MW{FAULT}"] == 6 and plc[f"%MW{STATE}"] == FAULT_STEP
    assert not plc["%Q0.2"] and plc["%MD112"] == pytest.approx(0, abs=1)


def test_piece_words_mark_a_cut_followed_by_a_cut_as_kind_3():
    from softplc.machines.cutting import load_piece, piece_words

    piece = load_piece(ROOT / "ladder_programs" / "pieces" / "escudo.toml")
    segs = piece.segments()
    kinds = [w.kind for w in piece_words(segs)]
    for i, (seg, k) in enumerate(zip(segs, kinds, strict=True)):
        following = segs[i + 1].kind if i + 1 < len(segs) else None
        want = 2 if seg.kind == "move" else 3 if following == "cut" else 1
        assert k == want, (i, seg.kind, following)
    assert kinds[0] == 2 and kinds[-1] == 1 and kinds.count(3) == len(segs) - 2


def test_a_frame_written_during_a_fault_is_refused_and_never_cut_after_reset():
    """Issue 23: a segment written while the machine is in FAULT stayed in the mailbox and
    ran, torch lit, at once after RESET. It is refused (INICIO := -1, which the host sees)
    and nothing moves after RESET until the host sends again."""
    plc = homed()
    plc.devices["estop"].press()
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == FAULT_STEP, timeout=0.1)
    offer(plc, 100_000, 0, 10.0, kind=1, number=2)  # the host, unaware of the fault
    plc.run(0.05)
    assert plc[f"%MW{INICIO}"] == -1  # refused, visibly
    plc.devices["estop"].release()
    plc.scan()
    plc["%M102"] = 1
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == READY, timeout=0.1)
    before = true_mm(plc)
    lit = False
    for _ in range(500):
        plc.scan()
        lit |= bool(plc["%Q0.2"]) or plc.devices["torch"].lit
    assert not lit and plc[f"%MW{STATE}"] == READY and plc[f"%MW{SEG_DONE}"] == 0
    assert true_mm(plc) == pytest.approx(before, abs=1e-4)
    offer(plc, 2_000, 0, 10.0, kind=1, number=3)  # the host sends again: it cuts
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 3, timeout=5)
    assert plc["%MD112"] == pytest.approx(2_000, abs=1)


def commanded_accels(plc: PLC, cruise: tuple[float, float], scans: int) -> list[float]:
    """The commanded accelerations (mm/s²) of both axes' first ramps: a parabola fitted to
    each axis's COMMANDED word (%MD +12, counts) against its servo tick count (%MD +20)
    times its tick period (the scan does not sample the ticks evenly)."""
    import numpy as np

    rows: dict[str, list[tuple[float, int]]] = {"X": [], "Y": []}
    for _ in range(scans):
        plc.scan()
        for axis, words in (("X", 200), ("Y", 230)):
            rows[axis].append((plc[f"%MD{words + 20}"] * plc.devices[axis].T,
                               plc[f"%MD{words + 12}"]))
    out = []
    for axis, v in zip(("X", "Y"), cruise, strict=True):
        t, c = np.array(rows[axis], float).T
        c /= COUNTS_PER_MM
        vel = np.diff(c) / np.diff(t)
        ramp = [i for i in range(1, len(vel)) if 0.05 * v < vel[i - 1] and vel[i] < 0.95 * v]
        assert len(ramp) >= 10
        out.append(2 * float(np.polyfit(t[ramp], c[ramp], 2)[0]))
    return out


@pytest.mark.parametrize("v", [2.0, 5.0])
def test_the_ramps_accelerate_at_exactly_a_times_u(v):
    """Issue 23: the ramp time was v/a + 1 ms, so the acceleration was 5 % low at 2 mm/s
    (20/21) and 2 % low at 5 mm/s (50/51). Now a_i = a·|u_i| (a = 100 mm/s²)."""
    plc = homed()
    offer(plc, 30_000, 40_000, v)  # u = (0.6, 0.8)
    ax, ay = commanded_accels(plc, (0.6 * v, 0.8 * v), int(1000 * v / 100) + 30)
    assert (ax, ay) == (pytest.approx(60.0, rel=2e-3), pytest.approx(80.0, rel=2e-3))


@pytest.mark.parametrize("piece_file,v", [("escudo.toml", 2.0), ("escudo.toml", 5.0),
                                           (None, 2.0)])
def test_the_planned_time_matches_the_plc_within_the_handshake(piece_file, v):
    """Issue 23: with exact ramps the motion time the host plans (L/v + v/a per segment,
    2·sqrt(L/a) for a line too short to reach v) is what the PLC takes, plus the
    handshake: one READY scan and the servo tick alignment, 0.5-2 ms per segment (it was
    about 1 ms more per segment with the v/a + 1 ms ramps, and 22 ms more for each
    10 µm triangle below, which ramped for 21 ms instead of 10)."""
    from softplc.machines.cutting import load_piece, piece_from_dict
    from softplc.machines.cutting.client import feed_plc

    if piece_file is None:  # ten 10 µm lines at 2 mm/s: triangles of 2 x sqrt(L/a) = 20 ms
        piece = piece_from_dict({"speed": v, "op": [
            {"kind": "line", "to": [0.01 * (i + 1), 0]} for i in range(10)]})
    else:
        piece = load_piece(ROOT / "ladder_programs" / "pieces" / piece_file, speed=v,
                           move_speed=v)
    plc = homed()
    t0 = plc.time
    n = feed_plc(plc, piece, timeout=60)
    extra = (plc.time - t0 - piece.duration()) / n
    assert 0.0005 <= extra <= 0.002


def test_home_from_ready_homes_again_and_is_ignored_while_cutting():
    plc = homed()
    offer(plc, 50_000, 20_000, 20.0, kind=2, number=1)
    plc.scan()
    plc["%M103"] = 1  # HOME while a segment runs: consumed, refused
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 1, timeout=10)
    assert not plc["%M103"] and plc["%MD112"] == pytest.approx(50_000, abs=1)
    plc.run(0.01)
    assert plc[f"%MW{STATE}"] == READY
    plc["%M103"] = 1
    plc.scan()
    plc.scan()
    assert plc[f"%MW{STATE}"] in (0, 1) and not plc["%M110"]  # searching again
    assert plc.run_until(lambda p: p[f"%MW{STATE}"] == READY, timeout=30)
    assert plc["%M110"] and plc[f"%MW{FAULT}"] == 0
    assert (plc["%MD112"], plc["%MD114"]) == (pytest.approx(0, abs=1), pytest.approx(0, abs=1))
    for axis in true_mm(plc):
        assert 29.47 <= axis <= 29.505


def test_g04_dwells_pierce_with_the_torch_lit_and_stand_still(tmp_path):
    """Issue 23: G04 is honoured, no longer dropped. Before a cut it is the pierce delay:
    the torch lights where the cut starts and the carriage stands still for P seconds;
    inside a contour the torch stays lit through it; with no cut after it, the torch is
    off. Each dwell is a segment (kind 4 lit, 5 off) timed by the PLC (%TM1)."""
    from softplc.machines.cutting import load_piece, piece_words
    from softplc.machines.cutting.client import feed_plc

    g = tmp_path / "pierce.gcode"
    g.write_text("G21 G90\nG00 X10 Y10\nG04 P0.5\nG01 X20 Y10 F600\nG04 P0.2\n"
                 "G01 X20 Y20\nG00 X0 Y0\nG04 P0.3\n", encoding="utf-8")
    piece = load_piece(g)
    segs = piece.segments()
    assert not piece.warnings
    assert [s.kind for s in segs] == ["move", "dwell", "cut", "dwell", "cut", "move", "dwell"]
    assert [w.kind for w in piece_words(segs)] == [2, 4, 3, 4, 1, 2, 5]
    assert [s.dwell for s in segs if s.kind == "dwell"] == [0.5, 0.2, 0.3]
    plc = homed()
    t0 = plc.time
    feed_plc(plc, piece, timeout=60)
    # the planned time (motion + 1.0 s of dwells) plus the handshake, 0.5-2 ms a segment
    assert 0.0005 <= (plc.time - t0 - piece.duration()) / len(segs) <= 0.002
    rows = [(s[0], s[1] / COUNTS_PER_MM, s[2] / COUNTS_PER_MM, s[3])
            for s in plc.devices["trace"].samples if s[0] >= t0]
    lit = [r for r in rows if r[3]]
    first, last = rows.index(lit[0]), rows.index(lit[-1])
    assert all(r[3] for r in rows[first:last + 1])  # one ignition: pierce, cut, pause, cut
    x0, y0 = lit[0][1], lit[0][2]

    def standing(x: float, y: float) -> float:  # lit and within 5 um of (x, y), s
        near = [r[0] for r in lit if abs(r[1] - x) < 0.005 and abs(r[2] - y) < 0.005]
        return near[-1] - near[0]

    # the pierce (+ the next ramp's first 5 um, 10 ms), then the pause at the corner (+ the
    # last 5 um of the cut arriving there, 10 ms more)
    assert 0.5 <= standing(x0, y0) <= 0.515
    assert 0.2 <= standing(x0 + 10, y0) <= 0.225
    assert not rows[-1][3]  # the last dwell (after a move) with the torch off


@pytest.mark.parametrize("kind,lit", [(4, True), (5, False)])
def test_a_dwell_lasts_its_seconds_torch_as_its_kind_says(kind, lit):
    plc = homed()
    offer(plc, 0, 0, 0.5, kind=kind, number=4)
    plc.scan()
    t0 = plc.time
    assert plc[f"%MW{EJECUTANDO}"] == 1 and plc["%Q0.2"] == lit
    assert plc.run_until(lambda p: p[f"%MW{SEG_DONE}"] == 4, timeout=2)
    assert plc.time - t0 == pytest.approx(0.5, abs=0.003)
    assert plc["%MD112"] == pytest.approx(0, abs=1) and plc["%MD114"] == pytest.approx(0, abs=1)


@pytest.mark.parametrize("kind,seconds,fault", [(4, 10.5, 6), (5, -0.1, 6), (6, 0.1, 6)])
def test_a_bad_dwell_is_fault_6(kind, seconds, fault):
    plc = homed()
    offer(plc, 0, 0, seconds, kind=kind)
    plc.run(0.05)
    assert plc[f"%MW{FAULT}"] == fault and not plc["%Q0.2"]


def test_a_long_dwell_is_split_into_dwells_the_plc_can_time():
    from softplc.machines.cutting import piece_from_dict, piece_words

    piece = piece_from_dict({"op": [{"kind": "move", "to": [5, 5]},
                                    {"kind": "dwell", "seconds": 25},
                                    {"kind": "line", "to": [10, 5]}]})
    segs = piece.segments()
    assert [s.dwell for s in segs] == [0.0, 9.999, 9.999, pytest.approx(5.002), 0.0]
    assert [w.kind for w in piece_words(segs)] == [2, 4, 4, 4, 1]
    assert piece.duration() == pytest.approx(25 + sum(
        2 * 0.0 + s.length / 2.0 + 2.0 / 100 for s in segs if s.kind != "dwell"))
