"""The drawing-table IL programs on the simulated machine (virtual clock, fast).

`ladder_programs/drawing_table.il` is the corrected program, `drawing_table_seed.il` the
seed's program rebuilt with its defects; both run with `drawing_table.toml`. The tests
drive the machine as the host does: between scans they write the ten-word frame
`X, Z, 20, 120, 40, Y, 60, 70, 85, 95` from %MW0 (INICIO = %MW3 = 120), and read
EJECUTANDO (%MW10) and INICIO back. Positions are in motor steps.
"""

from __future__ import annotations

import math
import random
from itertools import pairwise
from pathlib import Path

import pytest
from warm import simulated, warm

from softplc import PLC

PROGRAMS = Path(__file__).resolve().parents[2] / "ladder_programs"
CORRECTED = PROGRAMS / "drawing_table.il"
SEED = PROGRAMS / "drawing_table_seed.il"
CONFIG = PROGRAMS / "drawing_table.toml"

INICIO, Y_PEN, EJECUTANDO, FAULT = "%MW3", "%MW5", "%MW10", "%MW11"
BUSY = 100
STEP_PERIOD_S = 0.005  # TM0.P + TM1.P + 2 scans of 1 ms (drawing_table.toml)


def frame(x: int, z: int, y: int) -> list[int]:
    """The ten words the host writes with FC16 from %MW0."""
    return [x, z, 20, 120, 40, y, 60, 70, 85, 95]


def write_frame(plc: PLC, x: int, z: int, y: int = 0) -> None:
    for i, w in enumerate(frame(x, z, y)):
        plc[f"%MW{i}"] = w


def pos(plc: PLC) -> tuple[float, float]:
    return plc.devices["X"].position, plc.devices["Z"].position


def missed(plc: PLC) -> int:
    return plc.devices["X"].missed_steps + plc.devices["Z"].missed_steps


def samples(plc: PLC) -> list:
    return plc.trace


def scan_until(plc: PLC, cond, max_scans: int) -> int:
    """Scan one at a time until cond() holds; return the number of scans."""
    for n in range(1, max_scans + 1):
        plc.scan()
        if cond():
            return n
    raise AssertionError(f"condition not met after {max_scans} scans")


def distance_to_segment(p, a, b) -> float:
    (px, pz), (ax, az), (bx, bz) = p, a, b
    dx, dz = bx - ax, bz - az
    L2 = dx * dx + dz * dz
    t = 0.0 if L2 == 0 else max(0.0, min(1.0, ((px - ax) * dx + (pz - az) * dz) / L2))
    return math.hypot(px - (ax + t * dx), pz - (az + t * dz))


def homing_scans(start_steps: float) -> int:
    """Generous bound on the scans homing from start_steps takes."""
    return int((start_steps + 20) * STEP_PERIOD_S * 1000) + 50


def home(p: PLC) -> None:
    p.scan()
    assert p[EJECUTANDO] == BUSY
    scan_until(p, lambda: p[EJECUTANDO] == 0, homing_scans(500))


def homed(program: Path) -> PLC:
    """`program` on the machine, homed: restored to the state of one homing in this
    process (tests/warm.py; test_a_restored_homed_machine_draws_as_a_homed_one)."""
    return warm(("drawing_table", program), lambda: PLC.from_file(program, config=CONFIG),
                home)


@pytest.mark.parametrize("program", [CORRECTED, SEED], ids=["corrected", "seed"])
def test_a_restored_homed_machine_draws_as_a_homed_one(program):
    fresh = PLC.from_file(program, config=CONFIG)
    home(fresh)
    restored = homed(program)
    assert simulated(restored) == simulated(fresh)
    for p in (fresh, restored):
        write_frame(p, 300, 120, 1)
        p.scan(400)
    assert pos(fresh) != (0, 0) and simulated(restored) == simulated(fresh)


# ---- corrected program ------------------------------------------------------------------------
@pytest.fixture
def plc() -> PLC:
    """The corrected program, homed."""
    return homed(CORRECTED)


def draw(plc: PLC, x: int, z: int, y: int = 1) -> dict:
    """Send one segment as the host does; check the handshake; return what was seen."""
    start = pos(plc)
    n0 = len(samples(plc))
    write_frame(plc, x, z, y)
    plc.scan()
    assert plc[INICIO] == 0, "an idle PLC accepts the segment in the first scan"
    zero = (x, z) == start
    # EJECUTANDO is 100 in the very scan that accepts (clears INICIO), unless zero length
    assert plc[EJECUTANDO] == (0 if zero else BUSY)
    assert plc["%Q0.14"] == (y != 0)
    steps = max(abs(x - start[0]), abs(z - start[1]))
    scans = 1
    if not zero:
        scans += scan_until(plc, lambda: plc[EJECUTANDO] == 0,
                            int((steps + 3) * STEP_PERIOD_S * 1000) + 10)
    return {"start": start, "samples": samples(plc)[n0:], "scans": scans, "steps": steps}


def test_homing_comes_first_and_a_segment_waits_for_it():
    p = PLC.from_file(CORRECTED, config=CONFIG)
    x0, z0 = pos(p)
    assert x0 > 100 and z0 > 100, "the config starts the carriage away from home"
    p.scan()
    assert p[EJECUTANDO] == BUSY
    write_frame(p, 50, 50)  # a segment asked for during homing waits
    p.scan(200)
    x1, z1 = pos(p)
    assert x1 < x0 and z1 < z0, "both axes home together"
    assert p[INICIO] == 120, "no segment is accepted while homing"
    assert p[EJECUTANDO] == BUSY
    scan_until(p, lambda: p[INICIO] == 0, homing_scans(max(x0, z0)))
    # homing is over (both switches made) and the waiting segment is taken at once
    assert p.devices["home_X"].made and p.devices["home_Z"].made
    assert p[EJECUTANDO] == BUSY
    scan_until(p, lambda: p[EJECUTANDO] == 0, 400)
    assert pos(p) == (50, 50)
    assert missed(p) == 0


def test_homing_ends_exactly_at_zero(plc):
    assert pos(plc) == (0, 0)
    assert plc["%MW32"] == 0 and plc["%MW36"] == 0
    assert plc[FAULT] == 0
    assert missed(plc) == 0


@pytest.mark.parametrize("start_x", [332, 333, 334, 335])
def test_homing_from_any_rotor_phase_loses_no_step(start_x):
    """The power-up A+B alignment pulls the rotor whatever its phase: no opposite-phase miss."""
    p = PLC.from_file(CORRECTED, config=CONFIG)
    p.devices["X"].position = start_x
    p.scan()
    scan_until(p, lambda: p[EJECUTANDO] == 0, homing_scans(500))
    assert pos(p) == (0, 0)
    assert missed(p) == 0


SEGMENTS = {
    "horizontal": ((100, 200), (400, 200)),
    "vertical": ((100, 200), (100, 500)),
    "steep": ((100, 200), (160, 520)),
    "shallow": ((100, 200), (500, 330)),
    "diagonal": ((100, 200), (300, 400)),
    "reversed": ((400, 500), (100, 200)),
    "reversed_steep": ((300, 600), (250, 100)),
    "mixed_signs": ((100, 500), (300, 150)),
}


@pytest.mark.parametrize("name", list(SEGMENTS))
def test_segment_follows_the_line_and_arrives(plc, name):
    a, b = SEGMENTS[name]
    draw(plc, *a, y=0)  # travel to the start, pen up
    assert pos(plc) == a
    seen = draw(plc, *b, y=1)
    assert pos(plc) == b, "both axes arrive exactly"
    assert (plc["%MW32"], plc["%MW36"]) == b
    assert missed(plc) == 0
    pts = [(s[1], s[2]) for s in seen["samples"]]
    assert pts, "the trace recorded the move"
    worst = max(distance_to_segment(p, a, b) for p in pts)
    assert worst <= 1.0, f"trace leaves the line by {worst:.2f} steps"
    # one pulse per step of the major axis: both axes move together, never one after the
    # other, so the move takes max(|dx|, |dz|) pulses and every pulse moves the pen
    moves = sum(1 for p, q in pairwise([a] + pts) if p != q)
    assert moves == seen["steps"]
    assert seen["scans"] <= (seen["steps"] + 2) * STEP_PERIOD_S * 1000
    assert plc.devices["pen"].down


def test_random_segments(plc):
    """A fixed random walk over the whole table: exact arrival, on the line, no lost step."""
    rnd = random.Random(4)
    for _ in range(8):
        a = pos(plc)
        b = (rnd.randint(0, 2777), rnd.randint(0, 2777))
        seen = draw(plc, *b, y=rnd.randint(0, 1))
        assert pos(plc) == b
        assert all(distance_to_segment((s[1], s[2]), a, b) <= 1.0 for s in seen["samples"])
    assert missed(plc) == 0


def test_zero_length_segment(plc):
    draw(plc, 120, 80, y=0)
    seen = draw(plc, 120, 80, y=1)
    assert pos(plc) == (120, 80)
    assert all((s[1], s[2]) == (120, 80) for s in seen["samples"])
    assert plc[EJECUTANDO] == 0
    assert plc.devices["pen"].down, "the pen still follows Y"


def test_step_rate(plc):
    """200 steps/s: the oscillator period is TM0.P + TM1.P + 2 scans = 5 ms."""
    seen = draw(plc, 200, 0, y=0)
    ts = [s[0] for s in seen["samples"]]
    gaps = {round(b - a, 6) for a, b in pairwise(ts)}
    assert gaps == {STEP_PERIOD_S}
    assert plc.devices["X"].max_step_rate > 1 / STEP_PERIOD_S


def test_handshake_inicio_held_while_moving(plc):
    draw(plc, 50, 50, y=0)
    write_frame(plc, 300, 50, y=1)
    plc.scan()
    assert plc[INICIO] == 0 and plc[EJECUTANDO] == BUSY
    plc.scan(100)
    write_frame(plc, 300, 300, y=0)  # next segment written while the first one moves
    x_during = pos(plc)[0]
    assert 50 < x_during < 300
    for _ in range(20):
        plc.scan()
        assert plc[INICIO] == 120, "not accepted while moving"
        assert plc[EJECUTANDO] == BUSY
    assert plc["%Q0.14"], "the pen of the running segment is kept"
    # once the first segment arrives, the waiting one is accepted in that same wait
    scan_until(plc, lambda: plc[INICIO] == 0, 2000)
    assert plc[EJECUTANDO] == BUSY
    assert plc["%MW32"] == 300 and plc["%MW36"] == 50, "accepted exactly at the end point"
    assert not plc["%Q0.14"]
    scan_until(plc, lambda: plc[EJECUTANDO] == 0, 2000)
    assert pos(plc) == (300, 300)
    assert missed(plc) == 0


def test_exact_seed_frame(plc):
    """The host's ten words land in %MW0-%MW9; the PLC clears only INICIO."""
    write_frame(plc, 222, 111, 1)
    plc.scan()
    assert [plc[f"%MW{i}"] for i in range(10)] == [222, 111, 20, 0, 40, 1, 60, 70, 85, 95]
    assert plc[EJECUTANDO] == BUSY
    assert plc["%Q0.14"] and plc.devices["pen"].down
    scan_until(plc, lambda: plc[EJECUTANDO] == 0, 2000)
    assert pos(plc) == (222, 111)
    write_frame(plc, 222, 111, 0)
    plc.scan()
    assert not plc.devices["pen"].down


def test_segment_end_clamped_to_travel(plc):
    draw(plc, -40, 3000, y=0)
    assert pos(plc) == (0, 2777)
    assert not plc.devices["end_Z"].made
    assert missed(plc) == 0 and plc[FAULT] == 0


def test_broken_home_switch_stops_homing():
    """Homing gives up after %KW1 pulses (more than the travel) instead of running forever."""
    p = PLC.from_file(CORRECTED, config=CONFIG)
    p.devices["home_X"].set_fault("stuck_open")
    p.scan()
    scan_until(p, lambda: p[FAULT] == 1, 3100 * 5 + 100)
    x = pos(p)[0]
    assert pos(p)[1] == 0, "Z homed normally"
    p.scan(200)
    assert pos(p)[0] == x, "X stopped"
    write_frame(p, 100, 100)
    p.scan(20)
    assert p[INICIO] == 120 and p[EJECUTANDO] == BUSY, "no drawing after a homing fault"


# ---- the seed program: its documented defects -----------------------------------------------
@pytest.fixture
def seed() -> PLC:
    return homed(SEED)


def test_seed_homes_to_zero(seed):
    """From the configured start positions the seed's homing (DEC from 32000) ends at 0."""
    assert pos(seed) == (0, 0)
    assert seed["%MW32"] == 0 and seed["%MW36"] == 0


def test_seed_vertical_line_never_moves_z(seed):
    """SEED DEFECT: interpolation is driven by X alone; with XF = XI nothing steps, so a
    vertical line (0,0) -> (0,300) leaves Z at 0 and reports arrival at once."""
    write_frame(seed, 0, 300, 1)
    seed.scan()
    seed.scan(2000)
    assert pos(seed) == (0, 0)
    assert seed[EJECUTANDO] == 0
    assert seed["%MF42"] == 300.0, "the target was read (ZF), just never used"


def test_seed_z_slips_off_the_line(seed):
    """SEED DEFECT: rung 34 computes Z := A_B * B instead of A_B + B. From the origin B = 0,
    so Z stays 0 while X runs: the line (0,0) -> (300,150) is drawn along the X axis."""
    write_frame(seed, 300, 150, 1)
    n0 = len(samples(seed))
    seed.scan()
    scan_until(seed, lambda: pos(seed)[0] == 300, 300 * 20)
    seed.scan(100)
    assert pos(seed) == (300, 0), "Z ends at 0, not 150"
    worst = max(distance_to_segment((s[1], s[2]), (0, 0), (300, 150))
                for s in samples(seed)[n0:])
    assert worst > 100


def test_seed_ejecutando_flickers_mid_segment(seed):
    """SEED DEFECT (found by running the rebuild): EJECUTANDO := 0 whenever P_ALCANZ, and
    P_ALCANZ is true at every intermediate X step, so the host can read 0 (ready) in the
    middle of a segment."""
    write_frame(seed, 200, 0, 0)
    seed.scan()
    idle_mid_segment = 0
    while pos(seed)[0] < 190:
        seed.scan()
        if seed[EJECUTANDO] == 0:
            idle_mid_segment += 1
    assert idle_mid_segment > 100


def test_seed_accepts_a_segment_while_moving(seed):
    """SEED DEFECT: rung 30 takes INICIO at any time, even in the middle of a segment."""
    write_frame(seed, 300, 0, 0)
    seed.scan(200)
    assert 0 < pos(seed)[0] < 300
    write_frame(seed, 50, 0, 0)
    seed.scan()
    assert seed[INICIO] == 0


def test_seed_slope_is_computed_before_the_end_point_is_read(seed):
    """SEED DEFECT (found by running the rebuild): rung 31 computes DX, DZ and M from XF/ZF
    in the scan INICIO is taken, but rung 38 loads XF/ZF from %MW0/%MW1 only later in that
    scan, so M is the previous segment's slope: 0 after a completed segment. With
    `A_B + B` the seed would still draw every segment horizontally."""
    write_frame(seed, 100, 50, 1)
    seed.scan()
    assert seed["%MF50"] == 0.0, "M should be 0.5 for (0,0) -> (100,50)"
    assert seed["%MF46"] == 100.0 and seed["%MF42"] == 50.0, "XF, ZF loaded after M"


def test_seed_broken_home_switch_runs_forever():
    """SEED DEFECT: homing counts down from 32000 and stops only at the switch; with a
    broken X switch the axis drives into its mechanical stop and keeps losing steps."""
    p = PLC.from_file(SEED, config=CONFIG)
    p.devices["home_X"].set_fault("stuck_open")
    p.scan(3000)
    assert p.devices["X"].missed_steps > 100
    assert p["%M25"] and p[EJECUTANDO] == BUSY, "still homing"


# ---- the host-wait bit (both programs): [daemon] host_wait = "%M37" ---------------------------
HOST_WAIT = "%M37"
OSC_SCANS = round(STEP_PERIOD_S * 1000)  # scans per step-clock cycle (1 ms scan)
# what a waiting PLC still changes scan after scan: the step clock (its timers, PULSOS) and
# the system objects (scan counters, first-scan bit); the trace's next flush time
CLOCK_BLOCKS, PULSOS, TRACE_TIMER = ("TM", (0, 1)), 20, "_next_flush"


def frozen(plc: PLC) -> dict:
    """Everything but the step clock and the system objects: what must not change while
    the PLC waits for its host (then a held clock changes nothing a host can see)."""
    snap = plc.mem.snapshot()
    m = bytearray(snap.pop("m"))
    m[PULSOS] = 0
    family, clock = CLOCK_BLOCKS
    for k in ("s", "sw"):
        snap.pop(k)
    snap["blocks"][family] = {i: st for i, st in snap["blocks"][family].items()
                              if i not in clock}
    devices = {n: {k: v for k, v in d.state().items() if k != TRACE_TIMER}
               for n, d in plc.devices.items()}
    return {"m": bytes(m), **snap, "devices": devices}


def until_host_wait(plc: PLC, max_scans: int) -> dict:
    """Scan until %M37; check that a PLC that sets it shows the host "idle" (or a fault)
    and that scans meanwhile (several step-clock cycles) change nothing but the clock.
    Returns how many scans, and those where EJECUTANDO read 0 without the bit."""
    ready_early = 0
    for n in range(1, max_scans + 1):
        plc.scan()
        if not plc[HOST_WAIT]:
            ready_early += plc[EJECUTANDO] == 0
            continue
        assert plc[FAULT] or (plc[INICIO], plc[EJECUTANDO]) == (0, 0)
        before = frozen(plc)
        for _ in range(4 * OSC_SCANS):
            plc.scan()
            assert plc[HOST_WAIT]
        assert frozen(plc) == before, "a scan while waiting for the host changed something"
        return {"scans": n, "ready_early": ready_early}
    raise AssertionError(f"%M37 not set within {max_scans} scans")


def test_both_programs_name_the_host_wait_bit():
    for program in (CORRECTED, SEED):
        assert PLC.from_file(program, config=CONFIG).settings.daemon.host_wait_bit == 37


@pytest.mark.parametrize("program", [CORRECTED, SEED], ids=["corrected", "seed"])
def test_host_wait_only_where_a_scan_would_change_nothing(program):
    """%M37 (the daemon's host-wait bit: with --speed it runs no scan while the bit is 1
    and no write is pending) is 0 while homing and moving, and 1 once the move is over, at
    a point where further scans change nothing but the step clock: holding the virtual
    clock there is invisible, except that the host no longer waits for nothing."""
    p = PLC.from_file(program, config=CONFIG)
    homing = until_host_wait(p, homing_scans(500))
    assert pos(p) == (0, 0) and homing["scans"] > 300
    rnd = random.Random(5)
    # a random walk, a vertical line (the seed never moves Z), a zero-length segment
    targets = [(rnd.randint(0, 700), rnd.randint(0, 700)) for _ in range(5)]
    targets += [(targets[-1][0], 650), (targets[-1][0], 650)]
    early = 0
    for x, z in targets:
        steps = max(abs(x - pos(p)[0]), abs(z - pos(p)[1]), 700)  # the seed's Z: far
        write_frame(p, x, z, 1)
        early += until_host_wait(p, 2 * steps * OSC_SCANS + 20)["ready_early"]
        if program == CORRECTED:
            assert pos(p) == (x, z)
    # the corrected program: EJECUTANDO 0 without the bit only in the scan that takes the
    # zero-length segment (its one-scan DIFERENTE pulse is on); the seed: EJECUTANDO
    # flickers to 0 at every intermediate step target, the bit does not
    assert early == 1 if program == CORRECTED else early > 100


def test_a_fault_waits_for_the_host_too():
    """The corrected program in fault (homing timeout): nothing moves until a restart, so
    %M37 is 1 and the clock may stand still."""
    p = PLC.from_file(CORRECTED, config=CONFIG)
    p.devices["home_X"].set_fault("stuck_open")
    until_host_wait(p, 3100 * OSC_SCANS + 100)
    assert p[FAULT] == 1


def test_seed_waits_for_its_phase_to_catch_up_after_homing():
    """The seed zeroes TRAYEZ when PZ makes but updates the phase index only at the next
    PULSOS (rungs 21, 24): with a switch that makes off phase A (here: made early, at a
    count that is not a multiple of 4) that pulse still moves the motor, so %M37 waits
    for it."""
    p = PLC.from_file(SEED, config=CONFIG)
    scan_until(p, lambda: pos(p)[0] == 0 and pos(p)[1] % 4 == 1, homing_scans(500))
    p.devices["home_Z"].set_fault("stuck_closed")  # PZ makes here, off phase A
    scan_until(p, lambda: p["%MW36"] == 0, 2)  # the switch's input: the next scan's
    assert p["%MW37"] != 0, "the count is zeroed, the phase is not yet"
    until_host_wait(p, 2 * OSC_SCANS)
    assert p["%MW37"] == 0


def test_corrected_waits_for_the_alignment_pulse_when_already_home():
    """Started on both home switches (just past them) the corrected program is homed in
    its first scans, but the power-up alignment (phases A+B) lasts until the first PULSOS
    and phase A alone comes a scan later: %M37 waits for it."""
    p = PLC.from_file(CORRECTED, config=CONFIG)
    p.devices["X"].position = p.devices["Z"].position = -4
    scan_until(p, lambda: p[EJECUTANDO] == 0, 2)
    assert p["%M35"] and not p[HOST_WAIT]
    until_host_wait(p, 2 * OSC_SCANS)
    assert not p["%M35"] and pos(p) == (-4, -4)
