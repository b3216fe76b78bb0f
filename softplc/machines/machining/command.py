"""`softplc tune`: estimate a feed axis's reduced mass and write the matching parameters.

Offline mode: read the settings, the calibration and measurement recordings and the
template, estimate, pick the table row, write the parameter macro. Online mode (`--port`):
the same on each request the PLC raises over Modbus, answered with the result words
(`massest.handshake`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from softplc.commands._args import port
from softplc.errors import UncertaintyError

if TYPE_CHECKING:
    from softplc.machines.machining.estimator import Estimate
    from softplc.machines.machining.tuning import TuneResult

_EXAMPLES = """\
examples:
  softplc tune --example demo                  # sample inputs (22699 kg axis)
  softplc tune --dir demo --plot demo/fit.png  # estimate, write demo/MPSet.H
  softplc tune --dir demo --port 5020 --once   # answer one request (%MW401)
  softplc tune --compare fe.png --loads 18000 22699  # FE before/after retune
  softplc tune --settings s.txt --calibration IMCal_.dta \\
               --measurement IMMea_.dta --template MPSetTemp.H --output MPSet.H
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    # names from the light module, not `tuning`: the parser is built for every `softplc
    # --help`, which must not import numpy and the estimator
    from softplc.machines.machining import names

    p = subparsers.add_parser(
        "tune", help="estimate a feed axis's mass from scope recordings; write its parameters",
        description="Estimate the reduced mass of a feed axis from a calibration and a\n"
                    "measurement recording (least squares on the constant-acceleration\n"
                    "intervals), select the parameter-table row for that mass and write the\n"
                    "parameter macro (the template patched in place). Nothing is written\n"
                    "when the estimate is refused (exit status 1).",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    f = p.add_argument_group("files (default: the thesis's names in --dir)")
    f.add_argument("--dir", default=".", help="directory of the files (default %(default)s)")
    f.add_argument("--settings", help=f"settings and parameter table (default "
                                      f"{names.SETTINGS_FILE})")
    f.add_argument("--calibration", help=f"calibration recording (default {names.CAL_FILE})")
    f.add_argument("--no-calibration", action="store_true",
                   help="skip the current calibration (biased if the axis has a "
                        "position-dependent force)")
    f.add_argument("--measurement", help=f"measurement recording (default {names.MEAS_FILE})")
    f.add_argument("--template", help=f"parameter macro template (default "
                                      f"{names.TEMPLATE_FILE})")
    f.add_argument("--output", help=f"parameter macro to write (default {names.OUTPUT_FILE})")
    f.add_argument("--dry-run", action="store_true", help="estimate and select; write nothing")
    f.add_argument("--confirm", action="store_true",
                   help="show the mass and row and ask before writing (the thesis's mass "
                        "window); a refusal writes nothing (status 7 online)")
    o = p.add_argument_group("output")
    o.add_argument("--plot", metavar="OUT.png|OUT.svg",
                   help="figures of the intervals, fitted lines and current jumps")
    o.add_argument("--json", action="store_true", help="print the result as JSON")
    o.add_argument("--report", metavar="OUT.png|OUT.svg",
                   help="one report: fit, residuals, chosen row and the parameter "
                        "changes against the template; its data in OUT.json")
    m = p.add_argument_group(
        "online mode", "answer the PLC's requests over Modbus TCP (%MW401 EST_REQ,\n"
                       "result words %MW402-%MW463)")
    m.add_argument("--port", type=port, help="the PLC's Modbus TCP port (enables online mode)")
    m.add_argument("--host", default="127.0.0.1", help="PLC address (default %(default)s)")
    m.add_argument("--device-id", type=int, default=1, help="Modbus unit id (default 1)")
    m.add_argument("--connect-timeout", type=float, default=30.0, metavar="SECONDS",
                   help="wait this long for the daemon to listen (default %(default)s)")
    m.add_argument("--once", action="store_true", help="answer one request, then exit")
    m.add_argument("--wait", type=float, default=None, metavar="SECONDS",
                   help="give up after this long without a request (default: wait forever)")
    m.add_argument("--poll", type=float, default=0.1, metavar="SECONDS",
                   help="request polling interval (default %(default)s)")
    e = p.add_argument_group("sample inputs")
    e.add_argument("--example", metavar="DIR",
                   help="write sample inputs to DIR (settings, template, seeded synthetic "
                        "recordings) and exit")
    e.add_argument("--mass", type=float, default=22699.0,
                   help="mass of the sample axis, kg (default %(default)s)")
    e.add_argument("--seed", type=int, default=0, help="noise seed (default %(default)s)")
    e.add_argument("--no-noise", action="store_true", help="noise-free sample recordings")
    e.add_argument("--geometry", choices=names.GEOMETRIES, default="settings",
                   help="sample moves: the settings file's 300 mm at 0.22 m/s² or the NC "
                        "macro's 100 mm triangles at 0.4 m/s² (default %(default)s)")
    e.add_argument("--table", choices=names.TABLES,
                   help="parameter table: the thesis's (Fig. 3-40) or the simulated "
                        "machine's, one row per 3 t (default: thesis; machine with "
                        "--compare)")
    c = p.add_argument_group(
        "retune comparison on the simulated machine (mass_tuning.toml, no PLC)")
    c.add_argument("--compare", metavar="OUT.png|OUT.svg",
                   help="per load: FE of the measurement move, estimate, apply the row, "
                        "the same move again; plot and table (--table, --geometry, "
                        "--no-noise apply; default table: machine)")
    c.add_argument("--loads", type=float, nargs="+", default=[18000.0, 22699.0],
                   metavar="KG", help="moving masses to compare (default 18000 22699)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc.machines.machining import tuning

    if args.compare:
        return _compare(args)
    if args.example:
        paths = tuning.write_example(args.example, args.mass, args.seed, not args.no_noise,
                                     args.geometry, args.table or "thesis")
        for kind, path in paths.items():
            print(f"{kind:12s} {path}")
        return 0
    d = Path(args.dir)
    cal = None if args.no_calibration else (args.calibration or d / tuning.CAL_FILE)
    output = None if args.dry_run else (args.output or d / tuning.OUTPUT_FILE)
    settings = args.settings or d / tuning.SETTINGS_FILE

    def plot(est: Estimate) -> None:
        from softplc.machines.machining.plots import plot_estimate
        from softplc.machines.machining.settings import read_settings

        out = plot_estimate(est, read_settings(settings).a_lim_si, args.plot)
        print(f"figures written to {out}", file=sys.stderr)

    def once() -> tuning.TuneResult:
        try:
            res = tuning.tune_files(settings, cal, args.measurement or d / tuning.MEAS_FILE,
                                    args.template or d / tuning.TEMPLATE_FILE, output,
                                    _ask if args.confirm else None)
        except UncertaintyError as e:  # refused, but the figures show why
            if args.plot and e.estimate is not None:
                plot(e.estimate)
            raise
        if args.plot:  # each run (online: each request) redraws the figures
            plot(res.estimate)
        if args.report:
            from softplc.machines.machining.report import write_report
            from softplc.machines.machining.settings import read_settings

            paths = write_report(res, read_settings(settings).a_lim_si, args.report)
            print(f"report written to {paths[0]} and {paths[1]}", file=sys.stderr)
        return res

    if args.port is not None:
        return _online(args, once)
    res = once()
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


def _compare(args: argparse.Namespace) -> int:
    import tempfile

    from softplc.machines.machining.centre import compare_loads, markdown_table
    from softplc.machines.machining.plots import plot_following_error

    table = args.table or "machine"
    with tempfile.TemporaryDirectory() as tmp:
        res = compare_loads(args.loads, Path(tmp), table=table, geometry=args.geometry,
                            noise=not args.no_noise)
    panels = [(f"{r.load:g} kg: estimate {r.mass:.0f} kg -> row {r.row}, Ixx30 x "
               f"{r.kp_scale:.3f}",
               [(f"commissioned gains: peak {r.before.peak:.2f} µm", r.before.t, r.before.fe),
                (f"retuned (row {r.row}): peak {r.after.peak:.2f} µm", r.after.t, r.after.fe)])
              for r in res]
    out = plot_following_error(panels, args.compare, "following error of the measurement "
                               f"move ({args.geometry} geometry, {table} table)")
    if args.json:
        print(json.dumps([r.as_dict() for r in res], indent=2))
    else:
        print(markdown_table(res))
    print(f"figure written to {out}", file=sys.stderr)
    return 0


def _ask(res: TuneResult) -> bool:
    print(res.summary(), file=sys.stderr)
    try:
        answer = input("write these parameters? [y/N] ")
    except EOFError:
        answer = ""
    return answer.strip().lower() in ("y", "yes")


def _online(args: argparse.Namespace, once) -> int:
    from softplc.machines.machining.handshake import W_REQ, serve
    from softplc.modbus.host import ModbusHost

    host = ModbusHost(args.host, args.port, device_id=args.device_id, poll_interval=args.poll)
    host.connect_within(args.connect_timeout, lambda msg: print(msg, file=sys.stderr))
    try:
        print(f"waiting for estimation requests (%MW{W_REQ}) from {host.where}",
              file=sys.stderr)
        served = serve(host, once, once=args.once, timeout=args.wait)
    finally:
        host.close()
    return 0 if served and all(s.status == 0 for s in served) else 1
