"""`softplc tune`: estimate a feed axis's reduced mass and write the matching parameters.

Offline mode (today): read the settings, the calibration and measurement recordings and the
template, estimate, pick the table row, write the parameter macro. The online mode (wait for
the PLC's request over Modbus, write the result words) reuses `massest.tuning.tune`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

_EXAMPLES = """\
examples:
  softplc tune --example demo                      # write sample inputs (22699 kg axis)
  softplc tune --dir demo --plot demo/fit.png      # estimate, write demo/MPSet.H, plot
  softplc tune --settings s.txt --calibration IMCal_.dta --measurement IMMea_.dta \\
               --template MPSetTemp.H --output MPSet.H
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    from ..massest import tuning

    p = subparsers.add_parser(
        "tune", help="estimate a feed axis's mass from scope recordings; write its parameters",
        description="Estimate the reduced mass of a feed axis from a calibration and a "
                    "measurement recording (least squares on the constant-acceleration "
                    "intervals), select the parameter-table row for that mass and write the "
                    "parameter macro (the template patched in place). Nothing is written "
                    "when the estimate is refused.",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    f = p.add_argument_group("files (default: the thesis's names in --dir)")
    f.add_argument("--dir", default=".", help="directory of the files (default %(default)s)")
    f.add_argument("--settings", help=f"settings and parameter table (default "
                                      f"{tuning.SETTINGS_FILE})")
    f.add_argument("--calibration", help=f"calibration recording (default {tuning.CAL_FILE})")
    f.add_argument("--no-calibration", action="store_true",
                   help="skip the current calibration (biased if the axis has a "
                        "position-dependent force)")
    f.add_argument("--measurement", help=f"measurement recording (default {tuning.MEAS_FILE})")
    f.add_argument("--template", help=f"parameter macro template (default "
                                      f"{tuning.TEMPLATE_FILE})")
    f.add_argument("--output", help=f"parameter macro to write (default {tuning.OUTPUT_FILE})")
    f.add_argument("--dry-run", action="store_true", help="estimate and select; write nothing")
    o = p.add_argument_group("output")
    o.add_argument("--plot", metavar="OUT.png|OUT.svg",
                   help="figures of the intervals, fitted lines and current jumps")
    o.add_argument("--json", action="store_true", help="print the result as JSON")
    e = p.add_argument_group("sample inputs")
    e.add_argument("--example", metavar="DIR",
                   help="write sample inputs to DIR (settings, template, seeded synthetic "
                        "recordings) and exit")
    e.add_argument("--mass", type=float, default=22699.0,
                   help="mass of the sample axis, kg (default %(default)s)")
    e.add_argument("--seed", type=int, default=0, help="noise seed (default %(default)s)")
    e.add_argument("--no-noise", action="store_true", help="noise-free sample recordings")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..massest import tuning

    if args.example:
        paths = tuning.write_example(args.example, args.mass, args.seed, not args.no_noise)
        for kind, path in paths.items():
            print(f"{kind:12s} {path}")
        return 0
    d = Path(args.dir)
    cal = None if args.no_calibration else (args.calibration or d / tuning.CAL_FILE)
    output = None if args.dry_run else (args.output or d / tuning.OUTPUT_FILE)
    res = tuning.tune_files(args.settings or d / tuning.SETTINGS_FILE, cal,
                            args.measurement or d / tuning.MEAS_FILE,
                            args.template or d / tuning.TEMPLATE_FILE, output)
    if args.plot:
        from ..massest.plots import plot_estimate
        from ..massest.settings import read_settings

        s = read_settings(args.settings or d / tuning.SETTINGS_FILE)
        out = plot_estimate(res.estimate, s.a_lim_si, args.plot)
        print(f"figures written to {out}", file=sys.stderr)
    if args.json:
        e = res.estimate
        print(json.dumps({"mass": e.mass, "uncertainty": e.uncertainty,
                          "acceleration": e.acceleration, "beta": list(e.beta),
                          "row": res.row.number, "axis": res.values[0],
                          "values": {f"Q{q}": v for q, v in sorted(res.values.items())},
                          "output": str(res.output) if res.output else None}, indent=2))
    else:
        print(res.summary())
    return 0
