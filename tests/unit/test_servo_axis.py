"""The servo axis device on its own (no PLC program): plant, law, trajectories, the thesis's
published following errors (seed 002, TABLA 4-3), homing, faults, timing, config errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from daemon_util import ROOT

from softplc.devices.axis import Ctl, Err, Mode, St, Word
from softplc.devices.axis import trajectory as tj
from softplc.devices.axis.law import IVARS, Gains
from softplc.devices.axis.plant import step, thesis_zoh_coefficients, zoh_coefficients
from softplc.devices.axis.rig import Rig, load_axes
from softplc.errors import ConfigError

TOML = ROOT / "ladder_programs" / "servo_table.toml"
T = 4 / 9034.6  # Turbo PMAC2 default servo period
# The thesis move (TABLA 4-3): 14,336 counts at 4,177,920 counts/min, Ixx20/21 = 125/40 ms.
DIST, SPEED = 14336, 4_177_920 // 60
START = {"X": -80000, "Y": -128000}
PUBLISHED = {"X": 12.9, "Y": 11.8}  # max |FE|, counts
LINEAR = {"plant.coulomb": 0.0, "plant.amp_offset": 0.0, "ivars.Ixx29": 0,
          "ivars.Ixx68": 0, "plant.dac_bits": 0, "plant.encoder": "ideal"}


# -- plant -----------------------------------------------------------------------------------
def _zoh(A: np.ndarray, B: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """(Ad, Bd) of x' = A x + B u under a zero-order hold of T: the matrix exponential of
    the augmented matrix [[A, B], [0, 0]] T, exactly as scipy.signal.cont2discrete's
    "zoh" computes it (scipy 1.17 signal/_lti_conversion.py). scipy.linalg alone: importing
    scipy.signal costs several times more CPU, in every worker that runs this module."""
    from scipy.linalg import expm

    n, m = A.shape[0], B.shape[1]
    em = np.vstack((np.hstack((A, B)), np.zeros((m, n + m))))
    ms = expm(T * em)[:n, :]
    return ms[:, :n], ms[:, n:]


def _scipy_tf(K: float, a: float, T: float) -> tuple[float, float, float]:
    A = np.array([[0.0, 1.0], [0.0, -a]])
    B = np.array([[0.0], [K]])
    Ad, Bd = _zoh(A, B, T)
    # X/W = C (zI - Ad)^-1 Bd = (k1 z + k2) / ((z - 1)(z - p)), Ad upper triangular
    p = Ad[1, 1]
    k1 = Bd[0, 0]
    k2 = Ad[0, 1] * Bd[1, 0] - Ad[1, 1] * Bd[0, 0]
    return k1, k2, p


@pytest.mark.parametrize("K,a", [(11157.2, 4.975), (6478.7, 0.5), (1.0, 120.0), (11157.2, 0.0)])
def test_corrected_zoh_matches_scipy(K, a):
    k1, k2, p = zoh_coefficients(K, a, T)
    s1, s2, sp = _scipy_tf(K, a, T)
    assert k1 == pytest.approx(s1, rel=1e-9)
    assert k2 == pytest.approx(s2, rel=1e-9)
    assert p == pytest.approx(sp, rel=1e-12)


def test_thesis_zoh_formulas_are_wrong():
    """p = e^(B/J) is an unstable pole with no sample period; k2's p ln p sign is wrong."""
    K, a, T_ = 11157.2, 4.975, 442.74e-6
    k1, k2, p = zoh_coefficients(K, a, T_)
    assert thesis_zoh_coefficients(K, a, T_)[2] > 1 > p  # printed pole: unstable
    t1, t2, _ = thesis_zoh_coefficients(K, a, T_, p=p)  # even with the right p:
    assert t1 == pytest.approx(k1, rel=1e-9)  # k1 is right
    assert t2 / k2 == pytest.approx(1800, rel=0.01)  # k2 "1,800 times too large"


def test_plant_step_equals_the_discrete_state_space():
    K, a = 11157.2, 4.975
    A = np.array([[0.0, 1.0], [0.0, -a]])
    Ad, Bd = _zoh(A, np.array([[0.0], [K]]), T)
    x, v = 10.0, 3000.0
    for w in (12.0, -40.0, 0.5):
        ref = Ad @ np.array([x, v]) + Bd[:, 0] * w
        got = step(x, v, w, K, a, 0.0, T)
        assert got == pytest.approx(tuple(ref), rel=1e-10)
        x, v = got


def test_coulomb_friction_sticks_and_stops_at_zero_velocity():
    K, fc = 11157.2, 31.0
    assert step(5.0, 0.0, 30.0, K, 0.0, fc, T) == (5.0, 0.0)  # |w| <= fc: stuck
    x, v = step(0.0, 1.0, 0.0, K, 0.0, fc, T)  # slow, no drive: friction stops it
    assert v == 0.0 and 0 < x < 1.0 * T
    # breakaway: |w| > fc moves with w - fc
    x, v = step(0.0, 0.0, 41.0, K, 0.0, fc, T)
    assert v == pytest.approx(K * 10 * T)


# -- trajectory ------------------------------------------------------------------------------
def test_thesis_scurve_profile():
    rule = tj.RampRule(0.125, 0.040, 2.048e6)
    prof = tj.move(0.0, DIST, SPEED, rule)
    assert prof.duration == pytest.approx(0.33088, abs=1e-5)
    seg = prof.segments
    assert seg[0] == pytest.approx((0.040, 2.048e7, 0.0))  # jerk 50 m/s^3
    assert seg[1] == pytest.approx((0.045, 0.0, 819200.0))  # A = 2.0 m/s^2
    ramp = tj.Profile(0.0, 0.0, seg[:3]).end()
    assert ramp == pytest.approx((4352.0, SPEED))
    assert prof.end() == pytest.approx((DIST, 0.0), abs=1e-6)
    pts = tj.sample(prof, T)
    assert len(pts) == math.ceil(prof.duration / T)
    assert max(b - a for a, b in zip(pts, pts[1:], strict=False)) == pytest.approx(
        SPEED * T, rel=1e-9)


def test_short_move_and_acceleration_limit():
    rule = tj.RampRule(0.125, 0.040, 2.048e6)
    short = tj.move(0.0, 1000.0, SPEED, rule)  # shorter than V TA: no cruise
    assert short.end() == pytest.approx((1000.0, 0.0), abs=1e-6)
    assert short.duration == pytest.approx(0.25, rel=1e-6)
    limited = tj.RampRule(0.125, 0.040, 2.048e5)  # Ixx19 ten times lower: ramps stretched
    prof = tj.move(0.0, 100000.0, SPEED, limited)
    peak = max(abs(a) for _, _, a in prof.segments)
    assert peak == pytest.approx(2.048e5, rel=1e-9)
    assert prof.end() == pytest.approx((100000.0, 0.0), abs=1e-5)


# -- the thesis's following errors -----------------------------------------------------------
def scurve_test(axis: str, **overrides):
    """Close the loop at rest at the tuning start position, settle 0.5 s, run the move;
    returns (samples of the move, device)."""
    rig = Rig.from_toml(TOML, axis, start=START[axis], require_home=False, **overrides)
    dev = rig.axes[axis]
    rig.command(axis, Ctl.ENABLE)
    rig.run(0.5)
    n0 = len(dev.trace)
    rig.pulse(axis, Ctl.EXECUTE, target=round(dev.actual) + DIST, speed=SPEED, acc_ms=125,
              scurve_ms=40)
    rig.run(0.45)
    s = dev.samples()[n0:]
    return [(t - s[0][0] + T, cp, ap, fe, u) for t, cp, ap, fe, u in s], dev


@pytest.mark.parametrize("axis", ["X", "Y"])
def test_thesis_scurve_following_error(axis):
    s, _ = scurve_test(axis)
    fe = [r[3] for r in s]
    peak = max(abs(f) for f in fe)
    assert 0.6 * PUBLISHED[axis] <= peak <= 1.4 * PUBLISHED[axis], peak
    t = [r[0] for r in s]
    acc = [f for tt, f in zip(t, fe, strict=True) if tt <= 0.125]
    cruise = [f for tt, f in zip(t, fe, strict=True) if 0.135 <= tt <= 0.200]
    dec = [f for tt, f in zip(t, fe, strict=True) if 0.206 <= tt <= 0.331]
    hi, lo = max(acc, key=abs), max(dec, key=abs)
    assert hi > 0 > lo  # lagging while accelerating, leading while decelerating
    assert max(abs(f) for f in cruise) <= 0.5 * peak
    end = 0.33088
    settled = [tt for tt, f in zip(t, fe, strict=True) if tt >= end and abs(f) < 10]
    assert settled and settled[0] - end <= 0.005


@pytest.mark.parametrize("axis,linear", [("X", 13.9), ("Y", 9.6)])
def test_linear_reference_matches_the_spec_within_3_percent(axis, linear):
    s, _ = scurve_test(axis, **LINEAR)
    assert max(abs(r[3]) for r in s) == pytest.approx(linear, rel=0.03)


def test_without_feed_forward_the_error_is_the_velocity_lag():
    """Kvff = Kaff = 0 (and Ki = 0 so nothing else acts): in the cruise the law leaves
    Kp' FE = Kd' AV, i.e. FE = Ixx31 Ixx09 / (128 Ixx08) * V T = V * tau_d, tau_d =
    Ixx31 T / 128 = 10.96 ms for X: 763 counts, 55x the tuned error."""
    s, _ = scurve_test("X", **LINEAR, **{"ivars.Ixx32": 0, "ivars.Ixx35": 0, "ivars.Ixx33": 0})
    predicted = 3168 * 96 / (128 * 96) * SPEED * T
    assert predicted == pytest.approx(763.3, abs=0.5)
    end_cruise = [r[3] for r in s if r[0] <= 0.2058][-1]
    assert end_cruise == pytest.approx(predicted, rel=0.02)
    # with the tuned Ki the integral action takes some of it back, never adds to it
    s_ki, _ = scurve_test("X", **{"ivars.Ixx32": 0, "ivars.Ixx35": 0})
    peak = max(abs(r[3]) for r in s_ki)
    assert 30 * PUBLISHED["X"] < peak < predicted


def test_same_run_twice_gives_identical_traces():
    a, _ = scurve_test("X")
    b, _ = scurve_test("X")
    assert a == b


# -- timing ----------------------------------------------------------------------------------
@pytest.mark.parametrize("scan", [1e-3, 7e-3, 2.5e-3])
def test_servo_cycles_per_scan_carry_the_remainder(scan):
    cfg = {"X": {"type": "servo_axis", "plant": {"K": 1000.0}}}
    rig = Rig(cfg, scan=scan)
    per_scan = []
    for _ in range(round(7.0 / scan)):
        k = rig.axes["X"].k
        rig.step()
        per_scan.append(rig.axes["X"].k - k)
    assert rig.axes["X"].k == math.floor(7.0 * 9034.6 / 4)  # the exact long-run rate
    assert set(per_scan) <= {math.floor(scan / T), math.ceil(scan / T)}


def test_servo_cycle_extension_halves_the_loop_rate():
    rig = Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0}, "ivars": {"Ixx60": 1}}})
    rig.run(1.0)
    assert rig.axes["X"].k == math.floor(9034.6 / 8)


# -- homing, faults --------------------------------------------------------------------------
def enabled(axis: str = "X", **over) -> Rig:
    rig = Rig.from_toml(TOML, axis, **over)
    rig.command(axis, Ctl.ENABLE)
    rig.step()
    return rig


def test_homing_ends_at_the_index_mark():
    rig = enabled("X", start=-6000.0)
    dev = rig.axes["X"]
    assert not dev.homed
    rig.pulse("X", Ctl.HOME)
    assert rig.word("X", Word.STATUS) & St.HOMING
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.DONE, 10.0)
    st = rig.word("X", Word.STATUS)
    assert st & St.HOMED and st & St.IN_POSITION and not st & St.HOMING
    assert abs(dev.position) <= 10  # true position: the index mark at 0
    assert abs(rig.word("X", Word.ACTUAL, "d")) <= 10


def test_move_before_homing_is_a_fatal_error():
    rig = enabled("X")
    rig.pulse("X", Ctl.EXECUTE, target=-1000)
    st = rig.word("X", Word.STATUS)
    assert st & St.FE_FATAL and not st & St.ENABLED
    assert rig.word("X", Word.ERROR) == Err.NOT_HOMED
    rig.pulse("X", Ctl.RESET)
    st = rig.word("X", Word.STATUS)
    assert st & St.ENABLED and not st & St.ERROR  # reset with ENABLE held: loop closed


def homed(axis: str = "X", **over) -> Rig:
    rig = enabled(axis, require_home=False, **over)
    dev = rig.axes[axis]
    dev.homed = True
    dev.origin = -dev._enc0  # user coordinates = true positions, as after homing
    rig.step()
    return rig


def test_jammed_axis_trips_the_fatal_following_error():
    rig = homed("X", start=-50000.0)
    dev = rig.axes["X"]
    dev.set_fault("jammed")
    rig.pulse("X", Ctl.EXECUTE, target=-40000, speed=69632)
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.FE_WARNING, 1.0)
    assert rig.word("X", Word.ERROR) == Err.NONE
    assert rig.run_until(lambda: rig.word("X", Word.ERROR), 1.0)
    st = rig.word("X", Word.STATUS)
    assert rig.word("X", Word.ERROR) == Err.FATAL_FE
    assert st & St.FE_FATAL and not st & St.ENABLED
    assert rig.word("X", Word.OUTPUT, "f") == 0.0
    fe_at_kill = rig.word("X", Word.FE_MAX, "f")
    assert 4096 < fe_at_kill < 4200  # Ixx11 / 16
    rig.run(0.5)
    assert rig.word("X", Word.STATUS) & St.FE_FATAL  # latched
    dev.set_fault("none")
    rig.pulse("X", Ctl.RESET)
    st = rig.word("X", Word.STATUS)
    assert st & St.ENABLED and not st & St.FE_FATAL and st & St.HOMED


def test_estop_brakes_then_kills_through_the_amplifier_fault():
    rig = homed("X", start=-100000.0)
    dev = rig.axes["X"]
    rig.pulse("X", Ctl.EXECUTE, target=0, speed=69632)
    rig.run(0.3)
    assert dev.v > 60000
    dev.set_fault("estop")
    rig.step()
    assert rig.word("X", Word.ERROR) == Err.AMP_FAULT
    st = rig.word("X", Word.STATUS)
    assert st & St.ESTOP and st & St.AMP_FAULT and not st & St.ENABLED
    # braking at the drive's current limit (516 bits): v / (K 516) = 12 ms
    assert rig.run_until(lambda: dev.v == 0.0, 0.05)
    assert rig.t < 0.3 + 0.02
    dev.set_fault("none")
    rig.pulse("X", Ctl.RESET)
    assert rig.word("X", Word.STATUS) & St.ENABLED


@pytest.mark.parametrize("toml, start, speed", [
    ("servo_table.toml", -100_000.0, 69_632),  # Coulomb 31 bits, current limit 516
    ("cutting_table.toml", 12_340_000.0, 200_000)])  # frictionless, no current limit
@pytest.mark.parametrize("sign", [1, -1])
def test_estop_brakes_to_rest_without_sliding_back(toml, start, speed, sign):
    """The E-stop's braking ends where the velocity reaches 0: no servo tick carries the
    carriage back against its travel (a drive's quick stop, as PMAC's abort: decelerate
    to a stop, never reverse). With a = 0 the braking is a constant deceleration
    K (brake + Coulomb), so the rest position is known in closed form."""
    rig = Rig.from_toml(ROOT / "ladder_programs" / toml, "X", start=start,
                        require_home=False)
    dev = rig.axes["X"]
    rig.command("X", Ctl.ENABLE)
    rig.step()
    rig.pulse("X", Ctl.EXECUTE, target=sign * 400_000, speed=speed)  # (from the start)
    rig.run(0.3)
    x0, v0 = dev.x, dev.v
    assert sign * v0 > 0.9 * speed
    rig.scan_us = 100  # (a scan shorter than the servo period: one sample per tick)
    dev.set_fault("estop")
    seen = [x0]
    for _ in range(400):
        rig.step()
        seen.append(dev.x)
    assert all(sign * (b - a) >= 0 for a, b in zip(seen, seen[1:], strict=False)), "slid back"
    assert dev.v == 0.0 and seen[-100:] == [seen[-1]] * 100  # at rest, and stays
    p = dev.opt.plant
    brake = dev.u_peak if math.isfinite(dev.u_peak) else 32767.0
    assert seen[-1] == pytest.approx(x0 + sign * v0 * v0 / (2 * dev.K * (brake + p.coulomb)),
                                     abs=1e-6)


def test_limit_switch_blocks_the_drive_and_the_error_becomes_fatal():
    rig = homed("X", start=0.0)
    dev = rig.axes["X"]
    rig.pulse("X", Ctl.EXECUTE, target=20000, speed=20000)  # past END-1 at +4096
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.LIMIT_PLUS, 1.0)
    assert rig.run_until(lambda: rig.word("X", Word.ERROR), 2.0)
    assert rig.word("X", Word.ERROR) == Err.LIMIT
    assert 4096 <= dev.position < 6144  # stopped by the drive, before the hard stop
    assert not rig.word("X", Word.STATUS) & St.ENABLED


def test_open_loop_output_moves_the_commanded_way():
    """1 % of Ixx69 for 50 ms (TABLA 4-2): the full reference gives 1,801 counts at 50 ms."""
    rig = homed("X", start=-50000.0)
    dev = rig.axes["X"]
    x0 = dev.actual
    rig.pulse("X", Ctl.EXECUTE, mode=Mode.OPEN_LOOP, open_loop=100, acc_ms=50)
    assert rig.word("X", Word.STATUS) & St.OPEN_LOOP
    rig.run(0.049)
    assert dev.actual - x0 == pytest.approx(1801, rel=0.1)
    # then output 0: the carriage coasts on friction ("stops at ~9,300"), the loop closes
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.DONE, 1.0)
    assert dev.actual - x0 == pytest.approx(9300, rel=0.15)
    st = rig.word("X", Word.STATUS)
    assert st & St.ENABLED and not st & St.BUSY and not st & St.OPEN_LOOP


def test_step_and_parabolic_moves_reach_the_target():
    rig = homed("X", start=-50000.0)
    dev = rig.axes["X"]
    rig.pulse("X", Ctl.EXECUTE, target=-49900, mode=Mode.STEP)
    rig.step()
    assert rig.word("X", Word.STATUS) & St.DONE  # the command jumps at once
    rig.run(1.0)  # friction and the 12-bit DAC: the integrator creeps the last counts
    assert abs(dev.actual + 49900) <= 3
    t0 = rig.t
    rig.pulse("X", Ctl.EXECUTE, target=-45000, mode=Mode.PARABOLIC, acc_ms=200)
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.DONE, 1.0)
    assert rig.t - t0 == pytest.approx(0.2015, abs=0.002)  # the move's time
    rig.run(0.5)
    assert abs(dev.actual + 45000) <= 10  # Ixx28: the in-position band
    assert rig.word("X", Word.STATUS) & St.IN_POSITION


def test_pd_step_overshoot_is_that_of_the_autotune_design():
    """Row 6 of the spec: the gains are a 20 Hz, zeta = 0.7 design: PD only, a 100-count
    step overshoots by about 4 %."""
    rig = homed("X", start=-50000.0, **LINEAR, **{"ivars.Ixx32": 0, "ivars.Ixx33": 0,
                                                  "ivars.Ixx35": 0})
    dev = rig.axes["X"]
    x0 = dev.actual
    rig.pulse("X", Ctl.EXECUTE, target=round(x0) + 100, mode=Mode.STEP)
    peak = x0
    for _ in range(200):
        rig.step()
        peak = max(peak, dev.actual)
    assert 2.0 <= peak - x0 - 100 <= 7.0


def test_jog_and_stop():
    rig = homed("X", start=-50000.0)
    dev = rig.axes["X"]
    rig.command("X", Ctl.ENABLE | Ctl.JOG_MINUS)
    rig.run(0.3)
    assert dev.v == pytest.approx(-204800, rel=0.01)  # Ixx22 = 204.8 counts/ms
    rig.command("X", Ctl.ENABLE)
    rig.run(0.3)
    assert abs(dev.v) < 1000 and not rig.word("X", Word.STATUS) & St.BUSY


def test_load_and_mass_are_configuration_only():
    """A heavy table: twice the inertia and a 100-bit load; the loop still holds position
    and the current word shows the load."""
    rig = homed("X", start=-50000.0, **{"plant.load_mass_ratio": 1.0, "plant.load": 100.0,
                                        "plant.u_peak": 0.0})
    dev = rig.axes["X"]
    rig.run(3.0)
    assert abs(dev.actual + 50000) <= 3
    assert rig.word("X", Word.OUTPUT, "f") > 100 - 40  # friction takes up to 31 bits


# -- configuration ---------------------------------------------------------------------------
def test_ivars_by_either_name_and_errors_name_the_key():
    assert Gains(**{"Ixx30": 5}).kp == Gains(kp=5).kp == 5
    assert len({n for _, n, _, _ in IVARS}) == len(IVARS)
    with pytest.raises(ConfigError, match=r"ivars\.kpp"):
        Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0}, "ivars": {"kpp": 3}}})
    with pytest.raises(ConfigError, match=r"plant\.K"):
        Rig({"X": {"type": "servo_axis", "plant": {"K": -1.0}}})
    with pytest.raises(ConfigError, match=r"words"):
        Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0}, "words": "%MD3"}})


def test_status_words_are_declared_read_only():
    rig = Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0}, "words": "%MW300"}})
    assert rig.axes["X"].read_only_words() == [(310, 328)]


def test_a_parameter_given_by_both_names_is_an_error():
    with pytest.raises(ConfigError, match="Ixx30 and kp are the same parameter"):
        Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0},
                   "ivars": {"Ixx30": 1, "kp": 2}}})


def test_limit_switch_devices_watch_a_servo_axis():
    cfg = {"X": {"type": "servo_axis", "plant": {"K": 11157.2}, "start": -100.0,
                 "require_home": False, "geometry": {"limit_plus": 4096.0}},
           "home": {"type": "limit_switch", "axis": "X", "input": "%I0.12", "at": "home"},
           "end": {"type": "limit_switch", "axis": "X", "input": "%I0.13", "at": "end"}}
    rig = Rig(cfg)
    assert rig.devices["home"].made and not rig.devices["end"].made
    rig.axes["X"].x = 5000.0
    rig.step()
    assert not rig.devices["home"].made and rig.mem.i_field[13]


def test_servo_benchmark_runs_and_reports():
    """Smoke test of tools/bench_servo.py: figures well formed (never a speed threshold)."""
    import sys

    sys.path.insert(0, str(ROOT / "tools"))
    import bench_servo

    r = bench_servo.run(seconds=0.5)
    for part in ("device", "machine"):
        assert r[part]["speedup"] > 0 and r[part]["speedup_cpu"] > 0
        assert r[part]["faults"] == 0  # the axes moved all along, no fault stopped them
    assert r["device"]["servo_cycles"] >= 2 * math.floor(0.5 * 9034.6 / 4)
    assert "x real time" in bench_servo.report(r)


# -- one tick: commanded, actual and FE of the same servo tick (issue 23) --------------------
CUT_TOML = ROOT / "ladder_programs" / "cutting_table.toml"


def test_jog_words_and_stop_ramp_refer_to_the_same_tick():
    """The cutting table's axis (ideal encoder, 10 nm counts) jogging at Ixx22 = 10 mm/s:
    ACTUAL - COMMANDED = -FE (the old code read -443 counts = v T with FE 0); STOP then
    brakes over v^2 / 2a = 0.5 mm (Ixx20 = 100 ms trapezoid: a = 100 mm/s^2)."""
    rig = Rig.from_toml(CUT_TOML, "X", start=12_340_000.0, trace=True)
    ax = rig.axes["X"]
    rig.command("X", Ctl.ENABLE | Ctl.JOG_MINUS)
    rig.run(0.5)
    act, cmd = rig.word("X", Word.ACTUAL, "d"), rig.word("X", Word.COMMANDED, "d")
    fe = rig.word("X", Word.FE, "f")
    assert abs(fe) < 1 and abs(act - cmd + fe) <= 1
    k, cp, ap, _ = ax.trace[-1]  # the last row is the tick the words show
    assert k == rig.word("X", Word.TICKS, "d") and round(ap) == act and round(cp) == cmd
    rig.command("X", Ctl.ENABLE)
    rig.run(0.5)
    assert not rig.word("X", Word.STATUS) & St.BUSY
    braked = (act - rig.word("X", Word.ACTUAL, "d")) / 100_000  # mm
    assert braked == pytest.approx(0.5, abs=2e-5)


def test_moving_status_words_agree_with_the_last_trace_row():
    rig = homed("X", start=-50000.0)
    dev = rig.axes["X"]
    rig.pulse("X", Ctl.EXECUTE, target=-30000, speed=SPEED)
    for _ in range(150):  # every scan of the move: the words are the last row's tick
        rig.step()
        k, cp, ap, _ = dev.trace[-1]
        assert k == rig.word("X", Word.TICKS, "d") and ap == dev.actual
        assert rig.word("X", Word.ACTUAL, "d") == ap and round(cp) == rig.word(
            "X", Word.COMMANDED, "d")
        assert rig.word("X", Word.FE, "f") == pytest.approx(cp - ap, abs=1e-3)
    assert dev.v > 60000  # it was moving


def test_homed_rises_at_the_tick_the_encoder_reads_the_index():
    """The trigger tick's encoder count is the first past the index mark (the old code
    raised HOMED at the tick before, its count still short of the mark)."""
    rig = enabled("X", start=-6000.0)
    dev = rig.axes["X"]
    rig.pulse("X", Ctl.HOME)
    assert rig.run_until(lambda: dev.homed, 10.0)
    rig.step()
    rows = dev.trace
    # rows up to the trigger tick are in the coordinates before homing (origin 0)
    cut = next(i for i in range(len(rows) - 1, 0, -1) if rows[i][2] < rows[i - 1][2] - 1000)
    before, trigger = rows[cut - 2][2], rows[cut - 1][2]
    assert before < dev.origin <= trigger
    assert trigger - dev.origin <= 2  # homing speed x T = 1.5 counts per tick


# -- I-variables while running (issue 23) ----------------------------------------------------
def test_ivars_read_and_write_while_running_with_clear_errors():
    from softplc.devices.axis.ivars import IVarError

    rig = homed("X", start=-50000.0)
    iv = rig.axes["X"].ivars
    assert iv.get("I30") == iv.get("Ixx30") == iv.get("kp") == 7990
    iv.set("Ixx30", 8000)
    assert iv.get("kp") == 7990  # applied at the next tick boundary, not before
    rig.step()
    assert iv.get("kp") == 8000 and rig.axes["X"].coef.fe == pytest.approx(8000 * 96 / 2**19)
    for name, value, why in [("Ixx30", -1, "greater than or equal to 0"),
                             ("Ixx34", 2, "less than or equal to 1"),
                             ("Ixx60", 1, "configuration only"), ("Ixx99", 1, "unknown"),
                             ("Ixx08", 0, "greater than 0"), ("kp", math.nan, "finite")]:
        with pytest.raises(IVarError, match=why):
            iv.set(name, value)
    rig.step()
    assert iv.get("kp") == 8000  # nothing refused was applied


def test_a_gain_change_is_bumpless():
    """Holding a 100-bit load, the integrator carries it; doubling Ki and raising Kp by half
    at a tick would move the output by about 200 bits (the integral term scales with both);
    the change leaves it where it was (the integrator takes the difference)."""
    from softplc.devices.axis.law import Coefficients, law_output

    rig = homed("X", start=-50000.0, **LINEAR, **{"plant.load": 100.0})
    dev = rig.axes["X"]
    rig.run(2.0)
    u0 = dev.u
    assert u0 == pytest.approx(100, abs=1)  # the integrator holds the load
    new = dev.gains.model_copy(update={"ki": 2 * dev.gains.ki, "kp": dev.gains.kp * 1.5})
    naive = law_output(Coefficients.of(new), new, dev.fe, dev._cvp, 0.0, dev._ie,
                       0.0)  # (at rest: no acceleration, no velocity)
    assert abs(naive - u0) > 150  # what a plain change of coefficients would do
    dev.ivars.set("ki", new.ki)
    dev.ivars.set("kp", new.kp)
    n = len(dev.trace)
    rig.step()
    assert dev.gains.ki == new.ki
    outputs = [r[3] for r in dev.trace[n - 3:]]
    assert max(abs(u - u0) for u in outputs) < 1.0
    rig.run(1.0)
    assert abs(dev.actual + 50000) <= 1 and dev.u == pytest.approx(100, abs=1)


def test_load_disturbance_is_taken_up_by_the_integrator():
    """A 150-bit step of load torque while holding: the following error jumps, the
    integrator's term grows to the load and brings the error back to about zero; without
    an integrator (Ixx33 = 0) the error stays at load / Kp'."""
    def run(ki: float) -> tuple[float, float, list]:
        rig = homed("X", start=-50000.0, **LINEAR, **{"ivars.Ixx33": ki})
        dev = rig.axes["X"]
        rig.run(0.5)
        gather = dev.start_gather()
        dev.set_disturbance(150.0)
        rig.run(1.5)
        return max(abs(r[1] - r[2]) for r in gather), gather[-1][1] - gather[-1][2], gather

    peak, end, gather = run(ki=10193)  # the tuned X axis's Ixx33 (servo_table.toml)
    assert peak > 5 and abs(end) < 0.05 * peak
    assert gather[-1][4] == pytest.approx(150, rel=0.02)  # the integrator's term, bits
    _, end_p, _ = run(ki=0)
    kp = 7990 * 96 / 2**19  # Kp' in bits per count
    assert end_p == pytest.approx(150 / kp, rel=0.02)


# -- limit switches wired to the PMAC (issue 26) ---------------------------------------------
def limit_rig(wiring: str) -> Rig:
    """The cutting table's X axis (frictionless, 10 nm counts) 10 mm before an END-1 moved to
    100 mm, jogging into it at Ixx22 = 10 mm/s."""
    rig = Rig.from_toml(CUT_TOML, "X", start=9_000_000.0, **{
        "geometry.limit_plus": 10_000_000.0, "geometry.limit_wiring": wiring})
    rig.command("X", Ctl.ENABLE | Ctl.JOG_PLUS)
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.LIMIT_PLUS, 1.5)
    return rig


def test_a_limit_wired_to_the_pmac_aborts_at_ixx15_holds_and_allows_moving_away_only():
    """[manual: Turbo PMAC User Manual, hardware overtravel limits] The commanded trajectory
    stops at Ixx15 (limit_decel 10 counts/ms^2: 1e6^2 / 2e7 = 50,000 counts past the switch,
    plus <= 1 scan of travel), the loop stays closed and holds; a jog or a move further in
    is refused (error LIMIT, not latched), a jog away runs."""
    rig = limit_rig("pmac")
    ax = rig.axes["X"]
    rig.run(0.5)
    over = ax.position - 10_000_000
    assert 50_000 - 1 <= over <= 50_000 + 1_000 + 1
    st = rig.word("X", Word.STATUS)
    assert st & St.ENABLED and st & St.LIMIT_PLUS and not st & (St.BUSY | St.FE_FATAL | St.DONE)
    assert rig.word("X", Word.ERROR) == Err.LIMIT and ax.fe_max < 1000
    held = ax.position
    rig.run(1.0)  # JOG+ still held: nothing moves
    assert abs(ax.position - held) < 1.0 and abs(ax.v) < 1e-3
    rig.command("X", Ctl.ENABLE)
    rig.pulse("X", Ctl.RESET)
    assert rig.word("X", Word.ERROR) == Err.NONE
    rig.command("X", Ctl.ENABLE | Ctl.JOG_PLUS)  # a new jog into the limit: refused
    rig.run(0.3)
    rig.command("X", Ctl.ENABLE)
    rig.pulse("X", Ctl.EXECUTE, target=round(ax.commanded) + 100_000, speed=1_000_000)
    rig.run(0.3)
    assert abs(ax.position - held) < 1.0 and rig.word("X", Word.ERROR) == Err.LIMIT
    rig.command("X", Ctl.ENABLE | Ctl.JOG_MINUS)  # away from it
    rig.run(0.3)
    assert ax.position < held - 100_000 and not rig.word("X", Word.STATUS) & St.LIMIT_PLUS


def test_a_minus_limit_wired_to_the_pmac_stops_minus_moves_only():
    rig = Rig.from_toml(CUT_TOML, "X", start=9_000_000.0, **{
        "geometry.limit_minus": 8_000_000.0, "geometry.limit_wiring": "pmac"})
    ax = rig.axes["X"]
    rig.command("X", Ctl.ENABLE | Ctl.JOG_MINUS)
    assert rig.run_until(lambda: rig.word("X", Word.STATUS) & St.LIMIT_MINUS, 1.5)
    rig.run(0.5)
    assert 50_000 - 1 <= 8_000_000 - ax.position <= 50_000 + 1_000 + 1
    assert ax.closed and rig.word("X", Word.ERROR) == Err.LIMIT
    held = ax.position
    rig.command("X", Ctl.ENABLE)
    rig.pulse("X", Ctl.EXECUTE, target=round(ax.commanded) - 100_000, speed=1_000_000)
    rig.run(0.3)
    assert abs(ax.position - held) < 1.0
    rig.pulse("X", Ctl.EXECUTE, target=round(ax.commanded) + 200_000, speed=1_000_000)
    rig.run(0.5)
    assert ax.position == pytest.approx(held + 200_000, abs=5)


def test_a_drive_quick_stop_on_its_end_switch_ends_at_standstill():
    """Wired to the drive (the servo table's wiring) the END switch stops the carriage at the
    current limit and the PMAC's fatal error follows; the quick stop used to reverse the
    velocity, and the frictionless carriage then drifted back for ever once killed."""
    rig = limit_rig("drive")
    ax = rig.axes["X"]
    assert rig.run_until(lambda: rig.word("X", Word.ERROR), 2.0)
    assert rig.word("X", Word.ERROR) == Err.LIMIT and not ax.closed
    stopped = ax.position
    rig.run(1.0)
    assert ax.position == stopped >= 10_000_000 and ax.v == 0.0


# -- the generated scan of the common case (issue 26) -----------------------------------------
AXES = [("cutting_table.toml", 12_340_000.0),  # ideal encoder, frictionless, a = 0
        ("servo_table.toml", -50_000.0),  # friction, 12-bit DAC, integrator, trace
        ("mass_tuning.toml", -300_000.0)]  # viscous term, load table, current limit
# ... and with what the scan checks besides: the drive's READY wired to the E-stop input
# and the contactor output (the servo table's wiring), a load mass word
WIRED = [("servo_table.toml", -50_000.0, "estop"), ("servo_table.toml", -50_000.0, "contactor"),
         ("mass_tuning.toml", -300_000.0, "mass")]
MASS_RATIO = 0.25  # the load mass word's value from scan 600 (moving, jogging)
DROP_SCANS = (650, 680)  # the E-stop pressed (the contactor opened) while jogging, then back


def scenario(toml: str, start: float, tweak=None, extra: str = "") -> list:
    """Every scan's status words, state and last trace row: enable, a move, a jog, rest;
    `extra`: "estop", "contactor" (the drive wired, its contactor on, then that READY
    input dropped while jogging), "mass" (a new load mass while jogging)."""
    wired = extra in ("estop", "contactor")
    rig = Rig.from_toml(ROOT / "ladder_programs" / toml, "X", start=start,
                        require_home=False, wired=wired,
                        **({} if extra == "mass" else {"load_mass_word": None}))
    ax, b = rig.axes["X"], rig.base("X")
    if tweak is not None:
        tweak(ax)
    if wired:
        rig.mem.q_field[ax._power_idx] = True  # the contactor the program would close
    seen = []
    for scan in range(1200):
        if extra == "mass" and scan == 600:
            rig.mem.mw.set_f(ax._mass_word, MASS_RATIO)
        if extra == "estop" and scan in DROP_SCANS:
            rig.mem.i_field[ax._estop_idx] = scan == DROP_SCANS[0]
        if extra == "contactor" and scan in DROP_SCANS:
            rig.mem.q_field[ax._power_idx] = scan != DROP_SCANS[0]
        if scan == 1:
            rig.command("X", Ctl.ENABLE)
        elif scan == 300:
            rig.command("X", Ctl.ENABLE | Ctl.EXECUTE, target=round(start) + 40_000,
                        speed=200_000)
        elif scan == 302:
            rig.command("X", Ctl.ENABLE)
        elif scan == 500:
            rig.command("X", Ctl.ENABLE | Ctl.JOG_MINUS)
        elif scan == 700:
            rig.command("X", Ctl.ENABLE)
        rig.step()
        st = ax.state()
        for cache in ("trace", "_rest_words", "_st_slow"):  # (the scan's own caches)
            st.pop(cache)
        seen.append((bytes(rig.mem.mw.buf[2 * b:2 * (b + Word.SIZE)]), st,
                     ax.trace[-1] if ax.trace else None))
    return seen


@pytest.mark.parametrize("toml, start, extra", [(*a, "") for a in AXES] + WIRED)
def test_the_generated_scan_is_the_generic_update_bit_for_bit(monkeypatch, toml, start,
                                                               extra):
    """Every scan's status words, state and trace rows with the generated scan of the
    closed loop (moving, or at a fixed point) equal those of the generic update."""
    from softplc.devices.axis.runner import LoopRunner

    made, used = LoopRunner.scan_function, []

    def counted(self):  # (how many scans the generated scan did)
        fn = made(self)
        return None if fn is None else lambda *a: used.append(fn(*a)) or used[-1]

    monkeypatch.setattr(LoopRunner, "scan_function", counted)
    fast = scenario(toml, start, extra=extra)
    # (the rest: commands, the moves' ends, the probes; wired: the loop READY's drop opened)
    assert used.count(True) > (600 if extra in ("estop", "contactor") else 800)
    monkeypatch.setattr(LoopRunner, "scan_function", lambda self: None)
    generic = scenario(toml, start, extra=extra)
    for i, (f, g) in enumerate(zip(fast, generic, strict=True)):
        assert f == g, f"scan {i}"
    if extra in ("estop", "contactor"):  # READY's drop opened the loop (update's work)
        st = fast[DROP_SCANS[0]][1]
        assert not st["closed"] and not st["_ready"]
    if extra == "mass":  # the new mass is in force (the scan left the change to update)
        assert fast[-1][1]["load_mass_ratio"] == pytest.approx(
            MASS_RATIO + load_axes(ROOT / "ladder_programs" / toml, "X")["X"]["plant"]
            .get("load_mass_ratio", 0.0))


@pytest.mark.parametrize("toml, start", AXES)
def test_the_loops_folded_constants_change_no_bit(toml, start):
    """The loop without the folds that rest on u never being -0.0 (zero gains, no
    friction, no amplifier offset, no friction feed-forward) gives the same bits."""
    from softplc.devices.axis import loop

    def unfolded(ax) -> None:
        r = ax.runner
        r._flags.update(fc0=False, w_is_u=False, ff0=False, ca=True, av=True)
        c, off = ax.coef, ax.gains.offset
        r._values["law"] = loop.Raw(f"{c.fe!r} * fe + {c.cv!r} * cv + {c.ca!r} * ca + "
                                    f"{c.ie!r} * ie - {c.av!r} * av + {off!r}")
        r._loops.clear()
        ax._scan = r.scan_function()

    assert scenario(toml, start) == scenario(toml, start, unfolded)


# -- the generated scan's caches: an assignment from outside shows at once -------------------
CHANGES = {  # attribute -> its new value from the present one
    "homed": lambda v: not v, "done": lambda v: not v, "latched": lambda v: not v,
    "origin": lambda v: v + 1234, "error": lambda v: Err.BAD_COMMAND,
    "fe_max": lambda v: v + 99.0, "warn": lambda v: not v, "fe": lambda v: v + 3.0,
    "u": lambda v: v + 5.0, "w": lambda v: v + 7.0, "x": lambda v: v + 10.0,
    "closed": lambda v: not v, "fault": lambda v: "amp_fault"}


def _cut_axis() -> tuple[Rig, object]:
    rig = Rig.from_toml(ROOT / "ladder_programs" / "cutting_table.toml", "X")
    rig.command("X", Ctl.ENABLE)
    rig.step()
    return rig, rig.axes["X"]


def _words_are_the_state(rig: Rig, dev) -> None:
    """The status words the scan wrote are those the state gives, written in full."""
    b = rig.base("X")
    seen = bytes(rig.mem.mw.buf[2 * b:2 * (b + Word.SIZE)])
    dev.words.write()
    assert seen == bytes(rig.mem.mw.buf[2 * b:2 * (b + Word.SIZE)])


@pytest.mark.parametrize("name", CHANGES)
def test_an_assignment_at_rest_shows_in_the_next_scans_words(name):
    """At a fixed point the generated scan writes the words it kept; an attribute
    assigned from outside the device's methods shows in the very next scan."""
    rig, dev = _cut_axis()
    rig.run(0.05)
    assert dev._fixed and dev._rest_words is not None  # (the cached words are in use)
    setattr(dev, name, CHANGES[name](getattr(dev, name)))
    for _ in range(3):
        rig.step()
        _words_are_the_state(rig, dev)


@pytest.mark.parametrize("name", CHANGES)
def test_an_assignment_while_moving_shows_in_the_next_scans_words(name):
    """A moving axis's generated scan starts from the status bits kept by the last full
    write (`_st_slow`): an assignment from outside shows in the next scan too."""
    rig, dev = _cut_axis()
    rig.pulse("X", Ctl.EXECUTE, target=400_000, speed=200_000)
    rig.run(0.2)
    assert dev.v > 0 and dev._st_slow >= 0
    setattr(dev, name, CHANGES[name](getattr(dev, name)))
    for _ in range(3):
        rig.step()
        _words_are_the_state(rig, dev)


@pytest.mark.parametrize("name, value", [("v", 5000.0), ("u", 40.0), ("x", 12_340_500.0),
                                         ("_cp", 500.0)])
def test_an_assignment_to_the_loop_state_at_rest_ends_the_fixed_point(name, value):
    """The fixed point skips the servo cycles while the loop's state is unchanged: a
    state set from outside runs them again (the carriage moves, then settles)."""
    rig, dev = _cut_axis()
    rig.run(0.05)
    assert dev._fixed
    setattr(dev, name, value)
    x0, k0 = dev.x, dev.k
    rig.step()
    assert dev.k > k0 and dev.x != x0 and not dev._fixed


def test_a_snapshot_restores_the_caches_after_the_state_they_are_made_from():
    """set_state assigns STATE in order: the properties' setters drop the caches, so the
    caches must come after every property, or a restore would lose them (or keep stale
    ones)."""
    from softplc.devices.axis.servo import ServoAxis
    from softplc.devices.axis.state import LOOP_STATE, SHOWN

    at = ServoAxis.STATE.index
    assert set(LOOP_STATE + SHOWN) <= set(ServoAxis.STATE)
    assert max(map(at, LOOP_STATE + SHOWN)) < min(map(at, ("_fixed", "_creep", "_rest_words",
                                                           "_st_slow")))
    rig, dev = _cut_axis()
    rig.run(0.05)
    st = dev.state()
    assert st["_fixed"] and st["_rest_words"] is not None
    dev.set_state(st)
    assert dev._fixed and dev._rest_words == st["_rest_words"]
