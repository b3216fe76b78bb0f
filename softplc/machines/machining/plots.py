"""Figures of an estimate in the style of the thesis's Figs. 3-5, 3-10..3-15: acceleration
with the margin lines and intervals, velocity and current with the fitted line pairs, the
current jumps at the corners, and the calibration regression."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from softplc.machines.machining.estimator import Estimate


def plot_estimate(est: Estimate, a_lim: float, out: str | Path, title: str = "") -> Path:
    fig, _ = estimate_figure(est, a_lim, title)
    return _save(fig, out)


def estimate_figure(est: Estimate, a_lim: float, title: str = "", extra: int = 0,
                    height: float = 3.0) -> tuple[Any, list[Any]]:
    """The figure of `plot_estimate` with `extra` empty panels below (the report's)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = est.measurement
    kg = "kg·m²" if m.rotary else "kg"
    x_si, a_si = ("rad", "rad/s²") if m.rotary else ("m", "m/s²")
    panels = (4 if est.calibration is not None else 3) + extra
    fig, axs = plt.subplots(panels, 1, figsize=(11, height * panels), constrained_layout=True)
    axes = list(axs)
    colours = ("tab:red", "tab:green")
    ax = axes[0]
    ax.plot(m.t, m.a, lw=0.6, color="0.4", label="acceleration")
    for lvl in (a_lim / 2, -a_lim / 2):
        ax.axhline(lvl, ls="--", lw=0.8, color="tab:orange",
                   label="margin ±A_lim/2" if lvl > 0 else None)
    for i, sl in enumerate(est.intervals):
        ax.plot(m.t[sl], m.a[sl], ".", ms=2, color=colours[i // 2],
                label=f"intervals of pair {i // 2 + 1}" if i % 2 == 0 else None)
    c = list(est.crossings)
    ax.plot(m.t[c], m.a[c], "kx", ms=7, label="crossings (8)")
    ax.set_ylabel(f"acceleration [{a_si}]")

    ax = axes[1]
    ax.plot(m.t, m.v, lw=0.6, color="0.4", label="velocity")
    for j, p in enumerate(est.pairs):
        _fit_lines(ax, m.t, est.intervals[2 * j], est.intervals[2 * j + 1], p.corner, p.k,
                   p.b, colours[j], f"pair {j + 1}: |k| = {abs(p.k):.4f} {a_si}")
        ax.axvline(p.corner, lw=0.6, ls=":", color=colours[j])
    ax.set_ylabel(f"velocity [{x_si}/s]")

    ax = axes[2]
    ax.plot(m.t, est.corrected_current, lw=0.4, color="0.6", label="current (calibrated)")
    for j, p in enumerate(est.pairs):
        _fit_lines(ax, m.t, est.intervals[2 * j], est.intervals[2 * j + 1], p.corner,
                   p.k_current, p.b_current, colours[j], f"pair {j + 1} fit")
        i1 = p.b_current[0] + p.k_current * p.corner
        i2 = p.b_current[1] - p.k_current * p.corner
        ax.annotate("", xy=(p.corner, i2), xytext=(p.corner, i1),
                    arrowprops={"arrowstyle": "<->", "color": "k", "lw": 1.2})
        ax.plot([], [], color="k", label=f"jump {j + 1}: dI = {abs(p.jump):.3f} A")
    ax.set_ylabel("current [A]")
    ax.set_xlabel("time [s]")

    if est.calibration is not None:
        c = est.calibration
        ax = axes[3]
        scale = 1.0 if m.rotary else 1e3  # mm, or rad for a rotary axis
        ax.plot(c.x * scale, c.current, ",", color="0.5", label="calibration current",
                rasterized=True)  # 8192 points: a bitmap inside SVG
        xs = np.linspace(c.x.min(), c.x.max(), 2)
        ax.plot(xs * scale, est.beta[0] * xs + est.beta[1], color="tab:blue",
                label=f"I = {est.beta[0]:.4f} A/{x_si} · x + {est.beta[1]:.4f} A")
        # the moving samples set the scale (ramps carry m a and would flatten the picture)
        lo, hi = np.percentile(c.current, [5, 95])
        pad = 0.5 * (hi - lo) + 1e-3
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_xlabel("position [rad]" if m.rotary else "position [mm]")
        ax.set_ylabel("current [A]")
    for ax in axes[:panels - extra]:
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.suptitle(title or f"m = {est.mass:.1f} ± {est.uncertainty:.1f} {kg}")
    return fig, axes


def _save(fig: Any, out: str | Path) -> Path:
    import matplotlib.pyplot as plt

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _fit_lines(ax, t: np.ndarray, A: slice, B: slice, corner: float, k: float,
               b: tuple[float, float], colour: str, label: str) -> None:
    """The pair's two lines, from their interval to the corner where they meet."""
    ta = np.array([t[A][0], corner])
    tb = np.array([corner, t[B][-1]])
    ax.plot(ta, k * ta + b[0], color=colour, lw=1.4, label=label)
    ax.plot(tb, -k * tb + b[1], color=colour, lw=1.4)


def plot_following_error(panels: list[tuple[str, list[tuple[str, np.ndarray, np.ndarray]]]],
                         out: str | Path, title: str = "") -> Path:
    """One panel per load: following error (µm) over time (s) of the same move, one line
    per gain set; `panels` = [(panel title, [(label, t, fe), ...]), ...]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 2.8 * len(panels)),
                             constrained_layout=True, squeeze=False)
    for ax, (name, lines) in zip(axes[:, 0], panels, strict=True):
        for (label, t, fe), style in zip(lines, ("--", "-", ":"), strict=False):
            ax.plot(t, fe, style, lw=1.1, label=label)
        ax.axhline(0.0, lw=0.5, color="0.5")
        ax.set_title(name, fontsize=10)
        ax.set_ylabel("following error [µm]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1, 0].set_xlabel("time from the move's start [s]")
    if title:
        fig.suptitle(title)
    return _save(fig, out)
