"""Seeded, deterministic test recordings with a known mass (NOT an axis simulator).

Produces exactly the recording format (`Recording`), so the real recorder's output (the
servo device of the next round) can replace it. A scope run is: dwell, move out, dwell, move
back, dwell, sampled at t_i = i x Ts from the scope start; each move is a trapezoid (or
triangle) profile evaluated analytically; the force F = m a + F_c sgn v + c v + F0 + kx x
gives the torque M = F / p; then seeded Gaussian noise and the recorder's quantisation
(the channel FACTORs of the thesis's files).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from softplc.machines.machining.recording import THESIS_CHANNELS, Recording, quantise
from softplc.machines.machining.settings import Settings, thesis_settings

# SI value -> the thesis channels' DIM (mm, mm/min, m/(s*s), Nm)
_TO_DIM = (1e3, 6e4, 1.0, 1.0)
CAL_JOB, MEAS_JOB = 1, 2  # the scope's JOB numbers (IMCal_, IMMea_)


@dataclass(frozen=True)
class Run:
    """One scope recording: start -> end -> start at `feed` (m/s) and `accel` (m/s²)."""

    start: float  # m
    end: float  # m
    feed: float  # m/s
    accel: float  # m/s²
    dwell_before: float = 1.5  # s, from SCOPE START to the first move
    dwell_between: float = 0.5  # s (the macro's Q5)
    dwell_after: float = 1.5  # s, before SCOPE STOP
    jerk: float | None = None  # m/s³: S-curve (a CNC's FIR jerk filter); None = trapezoid


@dataclass(frozen=True)
class Scenario:
    """A synthetic axis and its two runs; defaults = the reference scenario (spec §6)."""

    mass: float = 22699.0  # kg, reduced mass
    ratio: float = 2 * math.pi / 0.012  # rad/m (12 mm lead)
    coulomb: float = 800.0  # N
    viscous: float = 3000.0  # N s/m
    pos_force: tuple[float, float] = (-328.1, -786.7)  # F0 N, kx N/m (the thesis's beta)
    noise: tuple[float, float, float, float] = (1e-6, 2e-4, 0.02, 0.5)  # x m, v m/s, a, Nm
    seed: int = 0
    sampling_us: int = 3000
    max_count: int = 8192
    measurement: Run = field(default_factory=lambda: Run(-0.45, -0.15, 0.2, 0.22))
    calibration: Run = field(default_factory=lambda: Run(-0.48, -0.12, 2.0 / 60, 1.0))

    def without_noise(self) -> Scenario:
        return replace(self, noise=(0.0, 0.0, 0.0, 0.0))


def macro_scenario(**kw: object) -> Scenario:
    """The thesis's macro geometry (INERT_MEAS_VS.H): 100 mm triangle moves at 0.4 m/s²,
    calibration over 160 mm at 2000 mm/min. Settings: `macro_settings()`."""
    return Scenario(measurement=Run(0.0, 0.1, 0.2, 0.4),
                    calibration=Run(-0.03, 0.13, 2.0 / 60, 1.0), **kw)  # type: ignore[arg-type]


def move_profile(tau: np.ndarray, distance: float, vmax: float, amax: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(x, v, a, duration) of a move of `distance` (> 0) starting at tau = 0; a triangle
    when the top speed is not reached."""
    if distance * amax >= vmax * vmax:
        ta, tc, vp = vmax / amax, distance / vmax - vmax / amax, vmax
    else:
        vp = math.sqrt(distance * amax)
        ta, tc = vp / amax, 0.0
    T = 2 * ta + tc
    tau = np.clip(tau, 0.0, T)
    up, cruise = tau < ta, tau < ta + tc
    td = T - tau  # time to the end, for the deceleration phase
    x = np.where(up, 0.5 * amax * tau**2,
                 np.where(cruise, 0.5 * amax * ta**2 + vp * (tau - ta),
                          distance - 0.5 * amax * td**2))
    v = np.where(up, amax * tau, np.where(cruise, vp, amax * td))
    a = np.where(up, amax, np.where(cruise, 0.0, -amax))
    # exactly at rest at both ends
    a = np.where((tau <= 0) | (tau >= T), 0.0, a)
    return x, v, a, T


JERK_TAPS = 32  # shifted copies averaged by the jerk filter


def kinematics(run: Run, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Position, velocity, acceleration of the run at times t (s from SCOPE START), and the
    run's total duration. With `jerk`, the trapezoid is averaged over a window of
    accel / jerk (a moving-average jerk filter): each shifted copy is an exact profile, so
    their mean is one too (x' = v, v' = a hold exactly), with a staircase jerk."""
    if run.jerk:
        window = run.accel / run.jerk
        shifts = (np.arange(JERK_TAPS) + 0.5) / JERK_TAPS * window
        parts = [_trapezoid_run(run, t - d) for d in shifts]
        x, v, a = (np.mean([p[i] for p in parts], axis=0) for i in range(3))
        return x, v, a, parts[0][3] + window
    return _trapezoid_run(run, t)


def _trapezoid_run(run: Run, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    d = abs(run.end - run.start)
    sgn = 1.0 if run.end > run.start else -1.0
    t1 = run.dwell_before
    x1, v1, a1, T = move_profile(t - t1, d, run.feed, run.accel)
    t2 = t1 + T + run.dwell_between
    x2, v2, a2, _ = move_profile(t - t2, d, run.feed, run.accel)
    x = run.start + sgn * (x1 - x2)
    v = sgn * (v1 - v2)
    a = sgn * (a1 - a2)
    return x, v, a, t2 + T + run.dwell_after


def force(sc: Scenario, x: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Axis force, N: inertia, Coulomb and viscous friction, position-dependent force."""
    f0, kx = sc.pos_force
    return sc.mass * a + sc.coulomb * np.sign(v) + sc.viscous * v + f0 + kx * x


def record(sc: Scenario, job: int) -> Recording:
    """The recording of one run (job CAL_JOB or MEAS_JOB), quantised as a scope stores it."""
    run = sc.calibration if job == CAL_JOB else sc.measurement
    _, _, _, total = kinematics(run, np.zeros(1))
    ts = sc.sampling_us * 1e-6
    count = min(sc.max_count, int(math.floor(total / ts + 1e-9)))
    t = np.arange(1, count + 1, dtype=np.int64) * sc.sampling_us * 1e-6
    x, v, a, _ = kinematics(run, t)
    torque = force(sc, x, v, a) / sc.ratio
    rng = np.random.default_rng([sc.seed, job])
    clean = (x, v, a, torque)
    cols = [quantise((val + rng.normal(0.0, sd, count)) * k, ch.factor)
            for val, sd, k, ch in zip(clean, sc.noise, _TO_DIM, THESIS_CHANNELS, strict=True)]
    name = "IMCal_.dta" if job == CAL_JOB else "IMMea_.dta"
    return Recording(THESIS_CHANNELS, sc.sampling_us, np.column_stack(cols), name)


def recordings(sc: Scenario) -> tuple[Recording, Recording]:
    """(calibration, measurement) recordings of the scenario."""
    return record(sc, CAL_JOB), record(sc, MEAS_JOB)


def macro_settings() -> Settings:
    """The thesis's settings (Fig. 3-1) with the macro geometry of `macro_scenario`."""
    return replace(thesis_settings(), start_cal=-30.0, end_cal=130.0, start_m=0.0,
                   end_m=100.0, a_lim=0.4, file="<macro settings>").validate()
