"""Plot the fast counter example (ladder_programs/fast_counter.il) around its first mark:
the very fast counter's value, the encoder's true pulse count, the reflex output %Q0.2
(switched by the counter at the encoder's 1 ms tick) and what a rung would do with the
same threshold (`LD %VFC0.TH0 / ST %Q0.6`, switched at the scans).

    .venv/bin/python tools/plot_fast_counter.py [--out docs/fast_counter.png]
                                                [--scan 7ms] [--window 0.95 1.12]

Prints the times the reflex output went on and off and the scans that saw it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from softplc.plc import PLC  # noqa: E402

PROGRAM = ROOT / "ladder_programs" / "fast_counter.il"
CONFIG = ROOT / "ladder_programs" / "fast_counter.toml"
SCAN_RUNG = "\nLD %VFC0.TH0\nANDN %VFC0.TH1\nST %Q0.6\n"  # the same window, by the program


def simulate(scan: str, t_end: float) -> tuple[list[tuple[float, int, int, int]], list]:
    text = PROGRAM.read_text().replace("\nEND\n", SCAN_RUNG + "END\n")
    plc = PLC.from_source(text, str(CONFIG), file=str(PROGRAM))
    plc.engine.period_us = round(float(scan.rstrip("ms")) * 1000)
    plc.devices["start"].press()
    rows = []
    while plc.time < t_end:
        plc.scan()
        rows.append((plc.time, plc["%VFC0.V"], plc.devices["belt_encoder"].pulses,
                     int(plc["%Q0.6"])))
    return rows, list(plc.mem.counting.events)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/fast_counter.png", help="PNG file to write")
    ap.add_argument("--scan", default="7ms",
                    help="scan period in ms (default 7ms: thresholds fall inside scans)")
    ap.add_argument("--window", nargs=2, type=float, default=(0.95, 1.12),
                    metavar=("T0", "T1"), help="time window to plot, s")
    a = ap.parse_args(argv)
    rows, events = simulate(a.scan, a.window[1])
    reflex = [(t, v) for t, _name, k, v in events if k == 0]
    for t, v in reflex:
        print(f"reflex %Q0.2 -> {v} at t = {t * 1000:.1f} ms")
    on_scans = [t for t, _v, _p, q in rows if q]
    if on_scans:
        print(f"the rung's %Q0.6 on from the scan ending at {on_scans[0] * 1000:.0f} ms to "
              f"{on_scans[-1] * 1000:.0f} ms")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0, t1 = a.window
    rows = [r for r in rows if t0 <= r[0] <= t1]
    ts = [r[0] * 1000 for r in rows]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True,
                                   gridspec_kw={"height_ratios": [2, 1]})
    ax1.plot(ts, [r[2] for r in rows], lw=1, label="encoder pulses (1 kHz: a line)")
    ax1.plot(ts, [r[1] for r in rows], "o", ms=3, label="%VFC0.V read by the scans")
    for s, name in ((1000, "S0"), (1050, "S1")):
        ax1.axhline(s, color="grey", ls=":", lw=1)
        ax1.text(ts[0], s, f" {name} = {s}", va="bottom", fontsize=8)
    ax1.set_ylabel("count (pulses)")
    ax1.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    # the reflex output as a step from its events; the rung's output per scan
    rx_t, rx_v, level = [t0 * 1000], [0], 0
    for t, v in reflex:
        if t0 <= t <= t1:
            rx_t += [t * 1000, t * 1000]
            rx_v += [level, v]
            level = v
    rx_t.append(t1 * 1000)
    rx_v.append(level)
    ax2.plot(rx_t, [v + 1.5 for v in rx_v], label="%Q0.2 reflex (counter, 1 ms tick)")
    ax2.step(ts, [r[3] for r in rows], where="post", label="%Q0.6 by a rung (scan)")
    ax2.set_yticks([0, 1, 1.5, 2.5], ["0", "1", "0", "1"])
    ax2.set_xlabel(f"time (ms), scan period {a.scan}")
    ax2.set_ylabel("output")
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    for ax in (ax1, ax2):
        for t in ts:
            ax.axvline(t, color="0.9", lw=0.5, zorder=0)
    ax1.set_title("Very fast counter: a threshold window counted between scans")
    fig.tight_layout()
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
