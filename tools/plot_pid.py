"""Plot the PID example (ladder_programs/pid_oven.il): auto-tuning, regulation at the set
point, then a set-point step, on the simulated oven (first order plus dead time).

    .venv/bin/python tools/plot_pid.py [--out results/pid_oven.png] [--step-at 1800]
                                      [--duration 3600] [--step-to 200]

Prints the auto-tuning's identified model and tuning, writes a PNG (temperature and set
point above, heater power below).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from softplc.plc import PLC
from softplc.runtime.pid import D_AT_DONE

ROOT = Path(__file__).resolve().parent.parent

PROGRAM = ROOT / "ladder_programs" / "pid_oven.il"
CONFIG = ROOT / "ladder_programs" / "pid_oven.toml"


def simulate(duration: float, step_at: float, step_to: float) -> dict:
    plc = PLC.from_file(PROGRAM, CONFIG)
    oven, pid = plc.devices["oven"], plc.mem.blocks["PID"][0]
    rows, at_end = [], None
    n = int(duration)
    for k in range(n):
        if k == int(step_at):
            plc["%MW10"] = round(step_to * 10)
        plc.run(1.0)
        if at_end is None and plc["%MW30"] & D_AT_DONE:
            at_end = plc.time
        rows.append((plc.time, oven.temperature, plc["%MW10"] / 10, pid.u / 100))
        if k % 600 == 0:
            print(f"\r  simulated {k}/{n} s", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return {"rows": rows, "at_end": at_end, "at": dict(pid.p.at_result)}


def plot(res: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, temp, sp, u = zip(*res["rows"], strict=True)
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(9, 6),
                                 gridspec_kw={"height_ratios": [2, 1]})
    a1.plot(t, temp, label="oven temperature")
    a1.plot(t, sp, "--", label="set point")
    a2.plot(t, u, color="tab:red", label="heater power (PID output)")
    for ax in (a1, a2):
        if res["at_end"]:
            ax.axvspan(0, res["at_end"], color="0.9", label="auto-tuning")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    a1.set_ylabel("temperature (°C)")
    a2.set_ylabel("power (%)")
    a2.set_xlabel("time (s)")
    at = res["at"]
    a1.set_title(f"PID 0 on the simulated oven: AT found K={at.get('K', 0):.3f}, "
                 f"T={at.get('T', 0):.0f} s, L={at.get('L', 0):.1f} s; "
                 f"Kp={at.get('Kp', 0):.1f}, Ti={at.get('Ti', 0):.0f} s", fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "pid_oven.png",
                    help="PNG file (default results/pid_oven.png)")
    ap.add_argument("--duration", type=float, default=3600.0, help="seconds (default 3600)")
    ap.add_argument("--step-at", type=float, default=1800.0,
                    help="time of the set-point step, s (default 1800)")
    ap.add_argument("--step-to", type=float, default=200.0,
                    help="new set point, degrees C (default 200)")
    args = ap.parse_args(argv)
    res = simulate(args.duration, args.step_at, args.step_to)
    print("auto-tuning:", ", ".join(f"{k}={v:.3f}" for k, v in res["at"].items()))
    plot(res, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
