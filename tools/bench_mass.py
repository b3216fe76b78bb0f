"""Machining-centre simulation speed (issue 14): one full measurement sequence of
mass_tuning.il on mass_tuning.toml (the settings file's geometry: calibration -480..-120 mm at
2000 mm/min, measurement -450..-150 mm at 12000 mm/min and 0.22 m/s², the macro's dwells;
about 59 s of machine time) at 1 ms scans: the PLC program, the servo axis at 3 kHz and the
recorder on the scan engine, started by the softkey, the host estimate run in the same
process when the PLC asks (its wall time included), until the parameters are applied.
Prints simulated seconds per wall (and CPU) second; target >= 50x.

    python tools/bench_mass.py
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import tomllib
from pathlib import Path

from bench_servo import _calib, _timed
from peers.common import speed_line

from softplc import PLC
from softplc.machines.machining import handshake, tuning

ROOT = Path(__file__).resolve().parent.parent

TOML = ROOT / "ladder_programs" / "mass_tuning.toml"
IL = ROOT / "ladder_programs" / "mass_tuning.il"
TARGET = 50.0
REQUEST_WAIT = 29
STATE = handshake.W_STATE  # %MW400, the Grafcet step


def sequence() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        tuning.write_example(d)  # settings and template (the recordings are replaced)
        conf = tomllib.loads(TOML.read_text(encoding="utf-8"))
        conf["devices"]["scope"]["directory"] = str(d)
        plc = PLC.from_file(IL, conf)
        plc.scan(3)
        plc["%M205"] = 1  # automatic mode
        plc["%M200"] = 1  # the softkey
        out: dict = {}
        mw = plc.mem.mw.w  # the step word read directly: plc["%MW400"] parses the address
        # at every scan, 7 % of the measured time, which no host of the daemon pays

        def go() -> None:
            if not plc.run_until(lambda p: mw[STATE] == REQUEST_WAIT, 120.0):
                raise RuntimeError(f"stuck in step {plc['%MW400']}")
            res = tuning.tune_files(d / tuning.SETTINGS_FILE, d / tuning.CAL_FILE,
                                    d / tuning.MEAS_FILE, d / tuning.TEMPLATE_FILE,
                                    d / tuning.OUTPUT_FILE)
            words = handshake.result_words(plc["%MW401"], res)
            for i, w in enumerate(words):  # as the host's one FC 16 frame
                plc.mem.mw.w[handshake.W_ACK + i] = w
            if not plc.run_until(lambda p: mw[STATE] == 0, 5.0):
                raise RuntimeError(f"not applied: step {plc['%MW400']}")
            out["mass"], out["row"] = res.estimate.mass, res.row.number

        t0 = plc.time
        r = _timed(go, 0.0)
        sim = plc.time - t0
        r.update(simulated_s=sim, speedup=sim / r["wall_s"], speedup_cpu=sim / r["cpu_s"],
                 scans=round(sim / plc.scan_period), **out)
        r["us_per_scan"] = r["wall_s"] / r["scans"] * 1e6
        plc.close()
        return r


def run() -> dict:
    return {"calib_ns": _calib(), "sequence": sequence(), "load_average": os.getloadavg()}


def report(r: dict) -> str:
    x = r["sequence"]
    return (f"Machining centre: one measurement sequence of mass_tuning.il at 1 ms scans "
            f"(tools/bench_mass.py; python loop {r['calib_ns']:.0f} ns/iter, load average "
            f"{r['load_average'][0]:.1f})\n"
            + speed_line(x, TARGET, us_digits=1,
                         extra=f"; estimate {x['mass']:.1f} kg -> row {x['row']}"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.parse_args(argv)
    print(report(run()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
