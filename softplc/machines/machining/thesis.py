"""The thesis's formulas AS PRINTED, wrong ones included: used only by tests and the docs
to show the defects. Never used by the estimator or `softplc tune`.

- eq. 3-9: the normal equations of the paired fit with ``-n1`` in X^T X (should be +n1);
- eq. 3-16: a = (k1 + k2) / 2 with signed slopes (the return move's slope is negative, so
  the sum nearly cancels; should be absolute values).
"""

from __future__ import annotations

import numpy as np

from softplc.machines.machining.estimator import Estimate, paired_fit


def thesis_normal_equations(tA: np.ndarray, yA: np.ndarray, tB: np.ndarray, yB: np.ndarray,
                            *, sign_error: bool = True) -> tuple[float, float, float]:
    """(k, b1, b2) from eq. 3-9 solved as printed (`sign_error=True`: -n1) or corrected."""
    n1 = -len(tA) if sign_error else len(tA)
    xtx = np.array([[np.sum(tA**2) + np.sum(tB**2), np.sum(tA), -np.sum(tB)],
                    [np.sum(tA), n1, 0.0],
                    [-np.sum(tB), 0.0, len(tB)]])
    xty = np.array([np.sum(tA * yA) - np.sum(tB * yB), np.sum(yA), np.sum(yB)])
    k, b1, b2 = np.linalg.solve(xtx, xty)
    return float(k), float(b1), float(b2)


def thesis_mass(est: Estimate, correction: float, km_sys: float, ratio: float, *,
                sign_error: bool = True, signed_mean: bool = True) -> float:
    """The mass of eqs. 3-10..3-17 on the intervals and calibrated current of `est`, with
    the printed sign error (eq. 3-9) and/or the signed mean acceleration (eq. 3-16)."""
    meas, cur = est.measurement, est.corrected_current
    fit = thesis_normal_equations if sign_error else (
        lambda tA, yA, tB, yB: paired_fit(tA, yA, tB, yB))
    ks, jumps = [], []
    for j in range(2):
        A, B = est.intervals[2 * j], est.intervals[2 * j + 1]
        k, b1, b2 = fit(meas.t[A], meas.v[A], meas.t[B], meas.v[B])
        kc, c1, c2 = fit(meas.t[A], cur[A], meas.t[B], cur[B])
        pr = (b2 - b1) / (2 * k)  # eq. 3-10
        ks.append(k)
        jumps.append(abs((c1 + pr * kc) - (c2 - pr * kc)))  # eq. 3-11, absolute (3-12 text)
    dI = (jumps[0] + jumps[1]) / 4  # eq. 3-12
    dF = km_sys * correction * dI * ratio  # eqs. 3-13, 3-15
    a = (ks[0] + ks[1]) / 2 if signed_mean else (abs(ks[0]) + abs(ks[1])) / 2  # eq. 3-16
    return dF / a  # eq. 3-17
