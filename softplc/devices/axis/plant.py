"""The axis plant: a double integrator with a viscous term, in PMAC units.

    x'' = K * w - a * x' - K * F_c * sgn(x')        (counts/s^2)

x in encoder counts, w the net drive command in DAC bits (the amplifier's input after its
offset and current limit, minus the load), K counts/s^2 per bit, a = B/J in 1/s, F_c the
Coulomb friction in bits. Between servo ticks w is held (zero-order hold), so the linear
part is integrated exactly with the closed-form ZOH update below; the Coulomb term is
exact too: a tick in which the velocity would change sign is split at the zero crossing
(found in closed form), and the carriage sticks there while |w| <= F_c (stiction).

The transfer function of the linear part, X/W = K / (s (s + a)), discretised with a ZOH
of period T (the corrected form of the thesis's chapter 1; see docs/machines/servo-table.md,
"The thesis reproduced", for what the thesis printed):

    X(z)/W(z) = (k1 z + k2) / ((z - 1)(z - p)),   p = exp(-a T)
    k1 = (K / a^2) (a T - 1 + p),   k2 = (K / a^2) (1 - p - a T p)
    a -> 0:  k1 = k2 = K T^2 / 2
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Below this a*T the closed forms lose digits to cancellation: use their series instead.
_SERIES_AT = 1e-4


def zoh_coefficients(K: float, a: float, T: float) -> tuple[float, float, float]:
    """(k1, k2, p) of the corrected ZOH transfer function above."""
    aT = a * T
    if aT < _SERIES_AT:
        # k1 = K T^2 (1/2 - aT/6 + (aT)^2/24), k2 = K T^2 (1/2 - aT/3 + (aT)^2/8)
        k1 = K * T * T * (0.5 - aT / 6 + aT * aT / 24)
        k2 = K * T * T * (0.5 - aT / 3 + aT * aT / 8)
        return k1, k2, math.exp(-aT)
    p = math.exp(-aT)
    return K / (a * a) * (aT - 1 + p), K / (a * a) * (1 - p - aT * p), p


def thesis_zoh_coefficients(K: float, a: float, T: float,
                            p: float | None = None) -> tuple[float, float, float]:
    """The thesis's printed formulas (chapter 1), kept only so a test can show them wrong:
    p = e^(B/J) (no sample period, wrong sign) unless `p` is given, and k2 with +p ln p."""
    if p is None:
        p = math.exp(a)  # as printed: p = e^(B/J)
    lnp = math.log(p)
    c = K * T / (a * lnp)  # r T / (B ln p) with K = r/J, a = B/J
    return c * (1 - p + lnp), c * (-1 + p + p * lnp), p


@dataclass(frozen=True)
class ZOH:
    """State update over a hold of length T: v' = phi v + K w g1, x' = x + v g1 + K w g2."""

    phi: float
    g1: float
    g2: float

    @classmethod
    def of(cls, a: float, T: float) -> ZOH:
        aT = a * T
        if aT < _SERIES_AT:
            g1 = T * (1 - aT / 2 + aT * aT / 6)
            g2 = T * T * (0.5 - aT / 6 + aT * aT / 24)
            return cls(math.exp(-aT), g1, g2)
        g1 = -math.expm1(-aT) / a
        return cls(math.exp(-aT), g1, (T - g1) / a)


def step(x: float, v: float, w: float, K: float, a: float, fc: float, T: float,
         zoh: ZOH | None = None, hold: bool = False) -> tuple[float, float]:
    """Exact state (x, v) after holding the net command w (bits) for T seconds, with
    Coulomb friction fc (bits) and stiction. The servo loop inlines the common case (no
    zero crossing) and calls this for the rest. `hold`: a braking drive that holds the
    carriage once the velocity reaches 0 within the period (a quick stop)."""
    z = zoh or ZOH.of(a, T)
    if v == 0.0:
        if -fc <= w <= fc:
            return x, 0.0  # stuck
        we = w - fc if w > 0 else w + fc
    else:
        we = w - fc if v > 0 else w + fc
    kw = K * we
    v1 = z.phi * v + kw * z.g1
    if v == 0.0 or (v > 0) == (v1 > 0) or v1 == 0.0:
        return x + v * z.g1 + kw * z.g2, v1
    # The velocity reaches 0 within the tick, at t0: integrate to it, then restart from rest.
    if a * T < _SERIES_AT:
        t0 = -v / kw
    else:
        c = kw / a  # terminal velocity
        t0 = -math.log(-c / (v - c)) / a
    t0 = min(max(t0, 0.0), T)
    z0 = ZOH.of(a, t0)
    x = x + v * z0.g1 + kw * z0.g2
    rest = T - t0
    if hold or rest <= 0.0 or -fc <= w <= fc:
        return x, 0.0
    return step(x, 0.0, w, K, a, fc, rest)
