"""PMACTuningPro's tuning moves on a simulated servo axis, gathered at the servo rate.

The axis is built from a machine TOML (`servo_table.toml` by default) on a bare memory
image (`Rig`), its loop closed at rest at the start position, then one move runs while
every servo tick is gathered (commanded, actual, following error, DAC output and the
integrator's share of it): what PMAC's data gathering gives the tuning tool, which
Modbus polling cannot. Moves: step, step-and-return with a dwell, parabolic, trapezoid,
S-curve. `metrics` gives rise time, overshoot, settling time and max |FE|; `plot` draws
one or two gain sets on the same move (overlay), their figures written on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softplc.devices.axis import Ctl, Err, Mode
from softplc.devices.axis.ivars import IVarError, resolve
from softplc.devices.axis.rig import Rig
from softplc.errors import SoftPLCError
from softplc.machines.examples import example

# The machine the commands simulate unless told (found from any working directory).
DEFAULT_CONFIG = example("servo_table.toml")
MOVES = ("step", "step-return", "parabolic", "trapezoid", "scurve")
MODES = {"step": Mode.STEP, "step-return": Mode.STEP, "parabolic": Mode.PARABOLIC,
         "trapezoid": Mode.TRAPEZOID, "scurve": Mode.SCURVE}


@dataclass
class Capture:
    """Servo-rate rows of one move: t ms from the command, CP, AP, FE (counts), output and
    integrator term (DAC bits)."""

    move: str
    label: str
    distance: int
    t: list[float] = field(default_factory=list)
    cp: list[float] = field(default_factory=list)
    ap: list[float] = field(default_factory=list)
    fe: list[float] = field(default_factory=list)
    out: list[float] = field(default_factory=list)
    integ: list[float] = field(default_factory=list)
    band: float = 10.0  # the in-position band (Ixx28), counts


def parse_gains(items: list[str]) -> dict[str, float]:
    """["I130=8000", "Ixx33=0", "kp=7000"] -> {"Ixx30": 8000.0, ...} (the motor digit is
    dropped: the axis is given apart)."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise IVarError(f"{item!r}: expected NAME=VALUE (I130=8000)")
        name = name.strip()
        if name[:1] in "Ii" and name[1:].isdigit() and len(name) == 4:
            name = "I" + name[2:]  # I130 -> I30 (motor 1)
        try:
            out[resolve(name)[0]] = float(value)
        except ValueError:
            raise IVarError(f"{item!r}: {value!r} is not a number") from None
    return out


def run_move(move: str, axis: str = "X", distance: int = 100, *, config: str | Path,
             start: float = -50000.0, gains: dict[str, float] | None = None, speed: int = 0,
             time_ms: int = 330, dwell_ms: int = 300, settle: float = 1.0,
             label: str = "") -> Capture:
    """One tuning move on a fresh simulated axis (homed, loop closed at `start` 0.5 s)."""
    if move not in MOVES:
        raise SoftPLCError(f"unknown move {move!r} (one of {', '.join(MOVES)})")
    rig, dev = _holding(config, axis, start, gains)
    cap = Capture(move, label, distance, band=dev.gains.in_position / 16)
    rows = dev.start_gather()
    k0 = dev.k
    x0 = round(dev.actual)
    mode = MODES[move]
    acc = time_ms if mode == Mode.PARABOLIC else 0
    rig.pulse(axis, Ctl.EXECUTE, target=x0 + distance, speed=speed, mode=mode, acc_ms=acc)
    if move == "step-return":
        rig.run(dwell_ms / 1000)
        rig.pulse(axis, Ctl.EXECUTE, target=x0, mode=mode)
    if not rig.run_until(lambda: dev.error or dev.done and not dev.motion.busy(), 30.0):
        raise SoftPLCError(f"the {move} move did not end within 30 s")
    rig.run(settle)
    if dev.error:  # an unstable gain set trips the fatal following error (Ixx11)
        raise SoftPLCError(f"{label or 'the configured gains'}: the {move} move ended in "
                           f"a fault: {Err.TEXT[dev.error]}")
    return _fill(cap, rows, k0, x0, dev.T)


def _holding(config: str | Path, axis: str, start: float, gains: dict[str, float] | None
             ) -> tuple[Rig, Any]:
    """A simulated axis of `config` (homed), its gains set, loop closed at `start` 0.5 s."""
    # a file that cannot be read, or has no device `axis`: ConfigError (softplc.config)
    rig = Rig.from_toml(config, axis, start=start, require_home=False)
    if axis not in rig.axes:
        raise SoftPLCError(f"{config}: device {axis!r} is not a servo_axis")
    dev = rig.axes[axis]
    for name, value in (gains or {}).items():
        dev.ivars.set(name, value)
    rig.command(axis, Ctl.ENABLE)
    rig.run(0.5)
    return rig, dev


def _fill(cap: Capture, rows: list, k0: int, x0: float, T: float) -> Capture:
    """The gathered rows into the capture: ms from the command, counts from x0."""
    for k, cp, ap, u, ie in rows:
        cap.t.append((k - k0) * T * 1000)
        cap.cp.append(cp - x0)
        cap.ap.append(ap - x0)
        cap.fe.append(cp - ap)
        cap.out.append(u)
        cap.integ.append(ie)
    return cap


def metrics(c: Capture) -> dict[str, float]:
    """Rise time (10-90 % of the first move, ms), overshoot (% of it), settling time (ms
    after the command's end until |FE| stays within Ixx28) and max |FE| (counts); a time
    the response never reaches within the gather is NaN."""
    d = c.distance
    last = max((i for i in range(1, len(c.cp)) if c.cp[i] != c.cp[i - 1]), default=0)
    t_end = c.t[last]  # the command's last change: the move's end
    first = [(t, ap) for t, ap in zip(c.t, c.ap, strict=True)]
    if c.move == "step-return":  # the figures of the first step (before the return)
        back = next((i for i, cp in enumerate(c.cp) if i and cp != d and c.cp[i - 1] == d),
                    len(c.cp))
        first = first[:back]
    s = 1 if d >= 0 else -1
    t10 = next((t for t, ap in first if s * ap >= 0.1 * abs(d)), float("nan"))
    t90 = next((t for t, ap in first if s * ap >= 0.9 * abs(d)), float("nan"))
    peak = max(s * ap for _, ap in first)
    out = [i for i, (t, fe) in enumerate(zip(c.t, c.fe, strict=True))
           if t >= t_end and abs(fe) > c.band]
    settle = (c.t[out[-1] + 1] if out and out[-1] + 1 < len(c.t) else
              (float("nan") if out else t_end)) - t_end
    return {"rise_ms": t90 - t10, "overshoot_pct": max(0.0, (peak - abs(d)) / abs(d) * 100)
            if d else 0.0, "settling_ms": settle, "max_fe": max(abs(f) for f in c.fe)}


def _ms(value: float, width: int = 0, digits: int = 1, unit: str = "") -> str:
    """A time figure; "never" where the response never got there (NaN)."""
    if not math.isfinite(value):
        return f"{'never':>{width}}"
    return f"{value:{width}.{digits}f}{unit}"


def table(caps: list[Capture]) -> str:
    """The figures of each capture, one line each (what the plot shows)."""
    rows = [f"{'gains':<28} {'rise ms':>8} {'overshoot %':>12} {'settling ms':>12} "
            f"{'max |FE| counts':>16}"]
    for c in caps:
        m = metrics(c)
        rise = _ms(m["rise_ms"], 8, 2) if c.distance else f"{'-':>8}"
        rows.append(f"{c.label or 'configured':<28} {rise} "
                    f"{m['overshoot_pct']:12.1f} {_ms(m['settling_ms'], 12, 1)} "
                    f"{m['max_fe']:16.2f}")
    return "\n".join(rows)


def plot(caps: list[Capture], out: str | Path, title: str = "") -> None:
    """Position (CP, AP), following error and output/integrator against time (ms), one
    colour per gain set; each set's figures in the legend, legends outside the data."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2, ax3) = plt.subplots(3, 1, sharex=True, figsize=(10, 8),
                                        gridspec_kw={"height_ratios": [3, 2, 2]})
    colours = ("tab:blue", "tab:red", "tab:green", "tab:purple")
    for c, col in zip(caps, colours, strict=False):
        m = metrics(c)
        name = c.label or "configured gains"
        figures = (f"rise {_ms(m['rise_ms'], unit=' ms')}, overshoot {m['overshoot_pct']:.1f} %\n"
                   if c.distance else "") + (
            f"settling {_ms(m['settling_ms'], unit=' ms')}, max |FE| {m['max_fe']:.1f} counts")
        if c is caps[0]:
            ax1.plot(c.t, c.cp, color="black", linewidth=1, label="commanded (CP)")
        ax1.plot(c.t, c.ap, color=col, linestyle="--", label=f"actual (AP), {name}\n{figures}")
        ax2.plot(c.t, c.fe, color=col, label=f"FE, {name}")
        ax3.plot(c.t, c.out, color=col, label=f"output, {name}")
        ax3.plot(c.t, c.integ, color=col, linestyle=":", label=f"integrator term, {name}")
    ax1.set_ylabel("position (counts)")
    ax2.set_ylabel("following error (counts)")
    ax3.set_ylabel("DAC (bits)")
    ax3.set_xlabel("time from the command (ms)")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0,
                  fontsize=8)
    ax2.axhline(0, color="black", linewidth=0.5)
    # the output's first ticks after a step hit the limit: scale to the rest
    rest = [u for c in caps for t, u in zip(c.t, c.out, strict=True) if t > 50] + \
        [u for c in caps for u in c.integ]
    if rest:
        lo, hi = min(rest), max(rest)
        pad = 0.1 * (hi - lo) + 1
        ax3.set_ylim(lo - pad, hi + pad)
    fig.suptitle(title or f"{caps[0].move} move, {caps[0].distance} counts "
                          "(servo-rate gather)")
    fig.tight_layout()
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)


def disturbance(axis: str = "X", bits: float = 150.0, *, config: str | Path,
                start: float = -50000.0, gains: dict[str, float] | None = None,
                seconds: float = 1.5, label: str = "") -> Capture:
    """Hold position, then a step of load torque (`bits`) at t = 0: the gathered response."""
    rig, dev = _holding(config, axis, start, gains)
    cap = Capture("disturbance", label, 0, band=dev.gains.in_position / 16)
    rows = dev.start_gather()
    k0 = dev.k
    x0 = round(dev.actual)
    dev.set_disturbance(bits)
    rig.run(seconds)
    return _fill(cap, rows, k0, x0, dev.T)
