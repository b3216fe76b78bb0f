"""Reduced-mass estimation by least squares (mass-estimation.md §2, thesis 3.3), corrected.

Model: F = m a + F_c sgn v + c v + F_pos(x), motor torque M = F / p, current I = -M / Km.
Per move (pair of constant-acceleration intervals A, B with accelerations +a, -a) the
velocity and the current are fitted by two lines of opposite slopes sharing |k|; the
current jumps by 2 m a / (Km p) where the velocity lines meet. Coulomb friction is equal in
A and B (same sgn v), viscous friction cancels exactly at the corner (same v); the
position-dependent force is removed by the calibration regression I = b1 x + b2.

    m = Correction Km p (|dI_1| + |dI_2|) / (2 (|k_1| + |k_2|)),  u = |m_1 - m_2| / 2
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from softplc.errors import (
    ChannelMismatchError,
    CrossingError,
    MassFileError,
    SingularFitError,
    UncertaintyError,
)
from softplc.machines.machining.recording import Recording
from softplc.machines.machining.settings import CHANNEL_ROLES, Settings

CROSSINGS = 8  # 4 constant-acceleration intervals: 2 moves x (accelerate, decelerate)
CAL_SPEED_FRACTION = 0.5  # calibration samples: |v| >= this x max |v| (no standstill)
MIN_FIT_SAMPLES = 3  # per interval, after trimming

# DIM -> its factor to SI; the settings' conversion must agree (never applied twice)
KNOWN_DIMS = {
    "mm": 1e-3, "m": 1.0, "um": 1e-6, "µm": 1e-6,
    "mm/min": 1e-3 / 60, "m/min": 1 / 60, "m/s": 1.0, "mm/s": 1e-3,
    "m/(s*s)": 1.0, "m/s^2": 1.0, "mm/(s*s)": 1e-3, "mm/s^2": 1e-3,
    "Nm": 1.0,
}
_DIM_TOLERANCE = 1e-4  # relative: Vel_conv 1.66667e-5 vs 1/60000


@dataclass(frozen=True)
class Trace:
    """One recording in SI units: t s, x m, v m/s, a m/s², current A (= -torque / Km)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    current: np.ndarray
    name: str = ""
    rotary: bool = False  # rad, rad/s, rad/s²: the "mass" is a moment of inertia, kg·m²


def to_trace(rec: Recording, s: Settings) -> Trace:
    """Map channels by ID (settings order: position, velocity, acceleration, torque), check
    units, convert with the settings' factors. Refuses flat traces."""
    got = sorted(c.id for c in rec.channels)
    if got != sorted(s.channel_ids):
        raise ChannelMismatchError(f"{rec.name}: channel IDs {got}, the settings ({s.file}) "
                                   f"expect {sorted(s.channel_ids)}")
    convs = (s.pos_conv, s.vel_conv, s.acc_conv, 1.0)
    cols = []
    for cid, conv, role in zip(s.channel_ids, convs, CHANNEL_ROLES, strict=True):
        ch = rec.channels[rec.channel_index(cid)]
        si = KNOWN_DIMS.get(ch.dim)
        if si is None or abs(conv / si - 1) > _DIM_TOLERANCE:
            raise ChannelMismatchError(
                f"{rec.name}: channel {cid} ({role}) is in {ch.dim!r}; the settings convert "
                f"with {conv:g}" + ("" if si is None else f", expected {si:g} for {ch.dim}"))
        col = rec.values(cid) * conv
        if np.ptp(col) == 0:
            raise SingularFitError(f"{rec.name}: channel {cid} ({role}) is flat "
                                   f"(all {col[0]:g}): nothing to fit")
        cols.append(col)
    x, v, a, torque = cols
    return Trace(rec.times(), x, v, a, -torque / s.km_sys, rec.name)


def fit_line(x: np.ndarray, y: np.ndarray, what: str) -> tuple[float, float]:
    """y = slope x + intercept by least squares."""
    X = np.column_stack([x, np.ones_like(x)])
    beta, _, rank, _ = np.linalg.lstsq(X, y, rcond=None)
    if rank < 2:
        raise SingularFitError(f"{what}: {len(x)} samples do not determine a line")
    return float(beta[0]), float(beta[1])


def calibrate(cal: Trace, s: Settings) -> tuple[float, float]:
    """(beta1 slope A/m, beta2 intercept A) of the calibration current over position.

    Samples strictly inside Start_Cal..End_Cal, moving at >= half the top speed and not
    accelerating (|a| <= A_lim / 2): standstill and ramps would carry friction steps and m a.
    """
    lo, hi = sorted((s.start_cal * s.pos_conv, s.end_cal * s.pos_conv))
    vmax = np.max(np.abs(cal.v))
    keep = ((cal.x > lo) & (cal.x < hi) & (np.abs(cal.v) >= CAL_SPEED_FRACTION * vmax)
            & (np.abs(cal.a) <= abs(s.a_lim_si) / 2))
    if np.count_nonzero(keep & (cal.v > 0)) < 2 or np.count_nonzero(keep & (cal.v < 0)) < 2:
        raise SingularFitError(f"{cal.name}: the calibration has no motion in both directions "
                               f"inside {lo:g}..{hi:g} m")
    return fit_line(cal.x[keep], cal.current[keep], f"{cal.name}: calibration")


def find_crossings(t: np.ndarray, a: np.ndarray, level: float, min_t: float) -> list[int]:
    """Samples where the acceleration crosses +level or -level (sign change of a - L between
    the previous sample and this one). After a crossing of one line, further crossings of
    that line within min_t are noise and ignored. At one sample crossing both lines, the
    line met first in the direction of travel comes first."""
    found: list[tuple[int, int, int]] = []  # (sample, order within the sample, line sign)
    for sign in (1, -1):
        above = a >= sign * level
        idx = np.nonzero(above[1:] != above[:-1])[0] + 1
        last = -math.inf
        for i in idx.tolist():
            if t[i] - last < min_t:
                continue
            last = t[i]
            falling = a[i] < a[i - 1]
            # falling: + line first; rising: - line first
            order = 0 if (sign > 0) == falling else 1
            found.append((i, order, sign))
    return [i for i, _, _ in sorted(found)]


def intervals(t: np.ndarray, a: np.ndarray, s: Settings, name: str = ""
              ) -> tuple[list[int], list[slice]]:
    """The 8 crossings and the 4 constant-acceleration intervals (c1,c2), (c3,c4), (c5,c6),
    (c7,c8), each trimmed by floor(Margin n) samples at both ends."""
    level = abs(s.a_lim_si) / 2
    cross = find_crossings(t, a, level, s.min_t)
    if len(cross) != CROSSINGS:
        at = (f" (at t = {', '.join(f'{t[i]:.3f}' for i in cross[:12])} s)" if cross else "")
        raise CrossingError(f"{name}: the acceleration crosses ±{level:g} m/s² {len(cross)} "
                            f"times{at}, expected {CROSSINGS}: check A_lim and MinT")
    out: list[slice] = []
    signs = []
    for j in range(0, CROSSINGS, 2):
        lo, hi = cross[j], cross[j + 1]
        cut = int(math.floor(s.margin * (hi - lo)))
        sl = slice(lo + cut, hi - cut)
        if sl.stop - sl.start < MIN_FIT_SAMPLES:
            raise SingularFitError(f"{name}: interval {j // 2 + 1} (t = {t[lo]:.3f}.."
                                   f"{t[hi]:.3f} s) keeps {sl.stop - sl.start} samples after "
                                   f"the margin, expected >= {MIN_FIT_SAMPLES}")
        out.append(sl)
        signs.append(float(np.sign(np.median(a[sl]))))
    if signs[0] == 0 or signs != [signs[0], -signs[0], -signs[0], signs[0]]:
        raise CrossingError(f"{name}: interval accelerations have signs {signs}, expected "
                            "(+,-,-,+) or (-,+,+,-): one move out and one back")
    return cross, out


def paired_fit(tA: np.ndarray, yA: np.ndarray, tB: np.ndarray, yB: np.ndarray,
               what: str = "pair") -> tuple[float, float, float]:
    """(k, b1, b2) of y = k t + b1 on A and y = -k t + b2 on B (one least-squares fit)."""
    X = np.zeros((len(tA) + len(tB), 3))
    X[:len(tA), 0], X[:len(tA), 1] = tA, 1.0
    X[len(tA):, 0], X[len(tA):, 2] = -tB, 1.0
    beta, _, rank, _ = np.linalg.lstsq(X, np.concatenate([yA, yB]), rcond=None)
    if rank < 3:
        raise SingularFitError(f"{what}: the paired fit is singular ({len(tA)} + {len(tB)} "
                               "samples)")
    return float(beta[0]), float(beta[1]), float(beta[2])


@dataclass(frozen=True)
class PairResult:
    k: float  # velocity slope, m/s² (signed)
    b: tuple[float, float]  # velocity intercepts, m/s
    corner: float  # pr: time where the velocity lines meet, s
    k_current: float  # current slope, A/s
    b_current: tuple[float, float]
    jump: float  # dI: current jump at the corner, A (signed)
    mass: float  # this pair's mass, kg


@dataclass(frozen=True)
class Estimate:
    mass: float  # kg
    uncertainty: float  # kg
    acceleration: float  # (|k1| + |k2|) / 2, m/s²
    beta: tuple[float, float]  # calibration slope A/m, intercept A
    pairs: tuple[PairResult, PairResult]
    intervals: tuple[slice, ...]
    crossings: tuple[int, ...]  # sample indices of the 8 margin-line crossings
    measurement: Trace
    calibration: Trace | None
    corrected_current: np.ndarray  # measurement current minus the calibration line

    @property
    def relative_uncertainty(self) -> float:
        return self.uncertainty / self.mass


def estimate_traces(meas: Trace, cal: Trace | None, s: Settings, *,
                    check_uncertainty: bool = True) -> Estimate:
    """The mass from a measurement trace; `cal=None` skips the calibration (beta = 0)."""
    beta = calibrate(cal, s) if cal is not None else (0.0, 0.0)
    current = meas.current - (beta[0] * meas.x + beta[1])
    cross, ivs = intervals(meas.t, meas.a, s, meas.name)
    gain = s.correction * s.km_sys * s.ratio
    pairs = []
    for j in range(2):
        A, B = ivs[2 * j], ivs[2 * j + 1]
        what = f"{meas.name}: pair {j + 1}"
        k, b1, b2 = paired_fit(meas.t[A], meas.v[A], meas.t[B], meas.v[B], what + " velocity")
        kc, c1, c2 = paired_fit(meas.t[A], current[A], meas.t[B], current[B],
                                what + " current")
        pr = (b2 - b1) / (2 * k)
        jump = (c1 + kc * pr) - (c2 - kc * pr)
        pairs.append(PairResult(k, (b1, b2), pr, kc, (c1, c2), jump,
                                gain * abs(jump) / (2 * abs(k))))
    k1, k2 = abs(pairs[0].k), abs(pairs[1].k)
    mass = gain * (abs(pairs[0].jump) + abs(pairs[1].jump)) / (2 * (k1 + k2))
    if not (math.isfinite(mass) and mass > 0):
        raise SingularFitError(f"{meas.name}: the current does not jump at the corners "
                               f"(mass {mass:g} kg)")
    est = Estimate(mass, abs(pairs[0].mass - pairs[1].mass) / 2, (k1 + k2) / 2, beta,
                   (pairs[0], pairs[1]), tuple(ivs), tuple(cross), meas, cal, current)
    if check_uncertainty and est.relative_uncertainty > s.acc_uncert:
        raise UncertaintyError(
            f"{meas.name}: m = {mass:.1f} ± {est.uncertainty:.1f} kg: relative uncertainty "
            f"{est.relative_uncertainty * 100:.3g} % exceeds Acc_uncert {s.acc_uncert * 100:g} %",
            est)
    return est


def as_trace(rec: Any, s: Settings) -> Trace:
    """A scope recording (checked against the settings) or a CSV one (own units) in SI."""
    return to_trace(rec, s) if isinstance(rec, Recording) else rec.to_trace(s)


def estimate(meas: Any, cal: Any, s: Settings, *, check_uncertainty: bool = True) -> Estimate:
    """Estimate the reduced mass from the measurement and calibration recordings (each a
    scope `Recording` or a `csvrec.CsvRecording`; cal None: no calibration)."""
    mt = as_trace(meas, s)
    ct = as_trace(cal, s) if cal is not None else None
    if ct is not None and ct.rotary != mt.rotary:
        raise ChannelMismatchError(f"{mt.name} and {ct.name}: one is rotary, the other linear")
    _check_range(mt, s)
    return estimate_traces(mt, ct, s, check_uncertainty=check_uncertainty)


POSITION_SLACK = 1e-3  # m: recorded positions may overshoot Start_m/End_m by this


def _check_range(meas: Trace, s: Settings) -> None:
    lo, hi = sorted((s.start_m * s.pos_conv, s.end_m * s.pos_conv))
    xmin, xmax = float(meas.x.min()), float(meas.x.max())
    if xmin < lo - POSITION_SLACK or xmax > hi + POSITION_SLACK:
        raise MassFileError(f"{meas.name}: positions {xmin:g}..{xmax:g} m leave the "
                            f"measurement range Start_m..End_m = {lo:g}..{hi:g} m")
