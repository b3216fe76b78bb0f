"""One report of a tuning run: a figure (PNG or SVG: the fit of `plot_estimate`, the fit
residuals of every interval, the chosen row and the parameter changes against the
template) and the same as JSON beside it (OUT.json).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from softplc.machines.machining.estimator import Estimate
from softplc.machines.machining.files import write_atomic
from softplc.machines.machining.params import AXIS_Q, MP_NAMES, MP_Q
from softplc.machines.machining.tuning import TuneResult, unit


def residuals(est: Estimate) -> list[dict[str, Any]]:
    """Per interval (pair j: A on +k, B on -k): times and the velocity and current
    residuals of the paired fits (data - line)."""
    m, cur = est.measurement, est.corrected_current
    out = []
    for j, p in enumerate(est.pairs):
        for side, sl in enumerate(est.intervals[2 * j:2 * j + 2]):
            sign = 1.0 if side == 0 else -1.0
            t = m.t[sl]
            out.append({"pair": j + 1, "interval": "AB"[side], "t": t,
                        "velocity": m.v[sl] - (sign * p.k * t + p.b[side]),
                        "current": cur[sl] - (sign * p.k_current * t + p.b_current[side])})
    return out


def parameter_changes(res: TuneResult) -> list[dict[str, Any]]:
    """Q0 and the 22 MPs: the template's value, the value written, changed or not."""
    names = [("Q0 (axis)", AXIS_Q)] + [(n, MP_Q[n]) for n in MP_NAMES]
    return [{"name": n, "q": q, "template": res.template.get(q), "new": res.values[q],
             "changed": res.template.get(q) != res.values[q]} for n, q in names]


def report_data(res: TuneResult) -> dict[str, Any]:
    e = res.estimate
    rms = [{"pair": r["pair"], "interval": r["interval"], "samples": len(r["t"]),
            "velocity_rms": float(np.sqrt(np.mean(r["velocity"] ** 2))),
            "current_rms_A": float(np.sqrt(np.mean(r["current"] ** 2)))}
           for r in residuals(e)]
    return {
        "measurement": e.measurement.name,
        "calibration": e.calibration.name if e.calibration is not None else None,
        "unit": unit(e), "rotary": e.measurement.rotary,
        "mass": e.mass, "uncertainty": e.uncertainty,
        "relative_uncertainty": e.relative_uncertainty, "acceleration": e.acceleration,
        "beta": list(e.beta),
        "pairs": [{"k": p.k, "corner_s": p.corner, "jump_A": p.jump, "mass": p.mass}
                  for p in e.pairs],
        "residuals": rms,
        "row": {"number": res.row.number, "inert": res.row.inert},
        "parameters": parameter_changes(res),
        "output": str(res.output) if res.output else None,
    }


def write_report(res: TuneResult, a_lim: float, out: str | Path) -> tuple[Path, Path]:
    """The figure at `out` (.png or .svg) and its data at `out` with suffix .json."""
    from softplc.machines.machining.plots import _save, estimate_figure

    e = res.estimate
    kg = unit(e)
    fig, axes = estimate_figure(e, a_lim, f"m = {e.mass:.1f} ± {e.uncertainty:.1f} {kg}, "
                                f"row {res.row.number}", extra=2, height=2.6)
    ax_r, ax_t = axes[-2], axes[-1]
    ax_v = ax_r.twinx()
    for r, colour in zip(residuals(e), ("tab:red", "tab:red", "tab:green", "tab:green"),
                         strict=True):
        label = f"pair {r['pair']}" if r["interval"] == "A" else None
        ax_r.plot(r["t"], r["current"], ".", ms=2, color=colour,
                  label=f"current, {label}" if label else None)
        ax_v.plot(r["t"], r["velocity"] * 1e3, lw=0.6, color="0.3", alpha=0.5,
                  label="velocity" if r["pair"] == 1 and label else None)
    ax_r.set_ylabel("current residual [A]")
    ax_v.set_ylabel("velocity residual [m" + ("rad/s]" if e.measurement.rotary else "m/s]"))
    ax_r.set_xlabel("time [s]")
    ax_r.grid(alpha=0.3)
    h1, l1 = ax_r.get_legend_handles_labels()
    h2, l2 = ax_v.get_legend_handles_labels()
    ax_r.legend(h1 + h2, l1 + l2, loc="upper left", bbox_to_anchor=(1.08, 1.0), fontsize=8)
    changes = [c for c in parameter_changes(res) if c["changed"]]
    lines = [f"table row {res.row.number} (inert >= {res.row.inert:g} {kg}); "
             f"{len(changes)} of {len(MP_NAMES) + 1} values differ from the template:"]
    lines += [f"  {c['name']:10s} {c['template']:>10g} -> {c['new']:<10g}" for c in changes]
    ax_t.axis("off")
    ax_t.text(0.0, 1.0, "\n".join(lines[:14]), va="top", family="monospace", fontsize=9,
              transform=ax_t.transAxes)
    fig_path = _save(fig, out)
    json_path = Path(out).with_suffix(".json")
    write_atomic(json_path, (json.dumps(report_data(res), indent=2) + "\n").encode())
    return fig_path, json_path
