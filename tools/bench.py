"""softplc benchmarks: scan engine, peers side by side, Modbus server load.

    .venv/bin/python tools/bench.py [--quick] [--json results/bench.json]
                                    [--png results/bench.png]
                                    [--sections engine,wordops,peers,modbus,drawing,servo,
                                                cutting,mass,startup]

Sections:
  engine  ns per boolean instruction, us per scan of ladder_programs/*.il (bench_engine.py)
  wordops ns per word line (%MW add, INC, %MD sub and div) and per timer / counter call
          of the compiled main() (bench_wordops.py; issue 26: <= 50 ns, <= 100 ns)
  peers   one table against pyrung, awlsim, a bare pymodbus server and libmodbus
          (bench_peers.py; `make bench` installs the optional peers)
  modbus  the daemon under Modbus load: throughput, latency, scan jitter (bench_modbus.py,
          skipped with a note if that file is absent)
  drawing simulated drawing speed: a 100-segment figure on the drawing table at a 1 ms
          scan, in simulated seconds per wall second (bench_drawing.py; target >= 50x)
  servo   servo table: two servo axes at 2.26 kHz, 1 ms scans, simulated seconds per wall
          and CPU second, devices alone and the whole machine (bench_servo.py; >= 50x)
  cutting cutting table: the rounded rectangle (E3) cut by cutting_table.il on two servo
          axes at 1 ms scans, simulated seconds per wall and CPU second (bench_cutting.py;
          >= 50x)
  mass    machining centre: one full mass-measurement sequence of mass_tuning.il at 1 ms
          scans with the host estimate, simulated s per wall and CPU s (bench_mass.py; >= 50x)
  startup CPU s of a whole `python -m softplc ...` process for commands that end soon
          after their start: --help, check, repl -x quit, plant down (bench_startup.py)

Figures go to stdout, progress to stderr; the JSON and the bar chart go under results/.
Absolute numbers vary from run to run and with whatever else the machine is doing (the
load average at the start is printed): compare ratios, and rerun before concluding.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from peers.common import describe_machine, machine_info, progress

ROOT = Path(__file__).resolve().parents[1]

def run_modbus_section(quick: bool) -> dict[str, Any]:
    """bench_modbus.run(...) if another part of the project provides it."""
    try:
        bench_modbus = importlib.import_module("bench_modbus")
    except ModuleNotFoundError as e:
        if e.name != "bench_modbus":
            raise
        return {"skipped": "tools/bench_modbus.py not present"}
    try:
        return {"results": bench_modbus.run(clients=(1, 8), duration=2.0 if quick else 3.0)}
    except Exception as e:  # a failing section is reported, the others still print
        return {"error": f"{type(e).__name__}: {e}"}


def modbus_report(res: dict[str, Any]) -> str:
    if "skipped" in res or "error" in res:
        return "Modbus load (bench_modbus): " + res.get("skipped", res.get("error", ""))
    r = res["results"]
    first = next(iter(r.values()), {})
    keys = [k for k, v in first.items() if isinstance(v, (int, float)) and k != "clients"]
    lines = ["Modbus load on the daemon (tools/bench_modbus.py, its built-in program, FC 3)",
             f"  {'':18}" + "".join(f"{n + ' client(s)':>14}" for n in r)]
    for k in keys:
        lines.append(f"  {k:18}" + "".join(
            f"{r[n].get(k, float('nan')):>14.3f}" if isinstance(r[n].get(k), float)
            else f"{r[n].get(k, '-'):>14}" for n in r))
    return "\n".join(lines)


def drawing_report(r: dict[str, Any]) -> str:
    return (f"Simulated drawing: {r['segments']} segments at a 1 ms scan, "
            f"{r['simulated_s']:.1f} simulated s in {r['wall_s']:.2f} wall s = "
            f"{r['speedup']:.0f}x real time ({r['us_per_scan']:.2f} us per scan with the "
            f"machine and the host loop; {r['missed_steps']} missed steps)  "
            f"target >= 50x  {'met' if r['speedup'] >= 50 else 'MISSED'}")


def _bench(name: str) -> Any:
    """A section's module, imported when the section runs: together they bring the PLC,
    the machines and numpy (a second of CPU), which a bad argument or --help need not."""
    return importlib.import_module(name)


def _report(name: str) -> Callable[[Any], str]:
    return lambda res: _bench(name).report(res)


# section -> (run it, given --quick; its report), in the order they run
SECTION_RUNS: dict[str, tuple[Callable[[bool], Any], Callable[[Any], str]]] = {
    "engine": (lambda quick: _bench("bench_engine").run(quick=quick), _report("bench_engine")),
    "wordops": (lambda quick: _bench("bench_wordops").run(
        200, 500 if quick else 2000, 3 if quick else 7), _report("bench_wordops")),
    "peers": (lambda quick: _bench("bench_peers").run(quick=quick), _report("bench_peers")),
    "modbus": (run_modbus_section, modbus_report),
    "drawing": (lambda quick: _bench("bench_drawing").run(segments=30 if quick else 100),
                drawing_report),
    "servo": (lambda quick: _bench("bench_servo").run(seconds=2.0 if quick else 5.0),
              _report("bench_servo")),
    "cutting": (lambda quick: _bench("bench_cutting").run(speed=10.0 if quick else 2.0),
                _report("bench_cutting")),
    "mass": (lambda quick: _bench("bench_mass").run(), _report("bench_mass")),
    "startup": (lambda quick: _bench("bench_startup").run(runs=3 if quick else 5),
                _report("bench_startup")),
}
SECTIONS = tuple(SECTION_RUNS)


def plot(res: dict[str, Any], path: Path) -> bool:
    """Bar charts: softplc vs peer scan time (log scale), Modbus requests/s per server.
    False when no section run has a chart (nothing written)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = _bench("bench_peers").rows(res["peers"]) if "peers" in res else []
    scans = [r for r in table if r["unit"] == "us/scan" and r["softplc"] and r["peer_value"]]
    mb = (res.get("peers") or {}).get("modbus") or {}
    servers = [s for s in ("libmodbus", "softplc", "pymodbus") if "fc3" in mb.get(s, {})]
    eng = res.get("engine")
    panels = [p for p, ok in (("scan", scans), ("modbus", servers), ("engine", eng)) if ok]
    if not panels:
        return False
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 3.6 * len(panels)), squeeze=False)
    for ax, panel in zip(axes[:, 0], panels, strict=True):
        if panel == "scan":
            labels = [f"{r['short']}\nvs {r['peer']}" for r in scans]
            x = range(len(scans))
            ax.bar([i - 0.2 for i in x], [r["softplc"] for r in scans], 0.4, label="softplc")
            ax.bar([i + 0.2 for i in x], [r["peer_value"] for r in scans], 0.4, label="peer")
            for i, r in enumerate(scans):
                ax.annotate(f"{r['advantage']:.0f}x", (i + 0.2, r["peer_value"]),
                            ha="center", va="bottom", fontsize=8)
            ax.set_yscale("log")
            ax.set_ylabel("us per scan (log)")
            ax.set_xticks(list(x), labels, fontsize=7)
            ax.set_title("Same logic, same scans: time per scan (lower is better)")
        elif panel == "modbus":
            cases = [(q, n) for q in ("fc3", "fc16") for n in ("1", "8")]
            w = 0.8 / len(servers)
            for k, s in enumerate(servers):
                ax.bar([i + (k - (len(servers) - 1) / 2) * w for i in range(len(cases))],
                       [mb[s][q][n]["requests_per_s"] for q, n in cases], w, label=s)
            ax.set_xticks(range(len(cases)), [f"{q.upper()} x10, {n} client(s)"
                                              for q, n in cases])
            ax.set_ylabel("requests/s")
            ax.set_title("Modbus TCP server, 127.0.0.1 (higher is better)")
        else:
            progs = [p for p in eng["programs"] if "error" not in p]
            names = ["boolean 1000 instr", "mixed 40 rungs"] + [p["program"] for p in progs]
            main = [eng["boolean"]["main_us"], eng["mixed40"]["main_us"]] + \
                [p["main_us"] for p in progs]
            scan = [eng["boolean"]["scan_us"], eng["mixed40"]["scan_us"]] + \
                [p["scan_us"] for p in progs]
            x = range(len(names))
            ax.bar([i - 0.2 for i in x], main, 0.4, label="compiled main()")
            ax.bar([i + 0.2 for i in x], scan, 0.4, label="plc.scan()")
            ax.set_xticks(list(x), names, fontsize=8)
            ax.set_ylabel("us per scan")
            ax.set_title("softplc scan engine")
        ax.legend(fontsize=8)
    info = res["machine"]
    fig.suptitle(f"softplc benchmarks - {info['cpus']} CPUs {info['cpu_model']}, Python "
                 f"{info['python']}", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="Absolute numbers vary from run to run; compare ratios.")
    ap.add_argument("--quick", action="store_true",
                    help="fewer scans and repeats, shorter Modbus load (about a minute)")
    ap.add_argument("--json", type=Path, default=ROOT / "results" / "bench.json",
                    help="write all figures as JSON here (default results/bench.json)")
    ap.add_argument("--png", type=Path, default=ROOT / "results" / "bench.png",
                    help="write the bar chart here (default results/bench.png)")
    ap.add_argument("--sections", default=",".join(SECTIONS),
                    help=f"comma-separated subset of {','.join(SECTIONS)}")
    a = ap.parse_args(argv)
    sections = [s.strip() for s in a.sections.split(",") if s.strip()]
    unknown = [s for s in sections if s not in SECTIONS]
    if unknown:
        ap.error(f"unknown section(s) {', '.join(unknown)}; known: {', '.join(SECTIONS)}")
    info = machine_info()
    res: dict[str, Any] = {"machine": info, "quick": a.quick, "sections": sections,
                           "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    print(f"Machine: {describe_machine(info)}")
    print(f"softplc {info['softplc']}, pymodbus {info['pymodbus']}"
          + (" (quick run)" if a.quick else ""))
    t0 = time.monotonic()
    for name, (run, report) in SECTION_RUNS.items():
        if name in sections:
            progress(f"section {name}")
            res[name] = run(a.quick)
            print("\n" + report(res[name]))
    res["seconds"] = time.monotonic() - t0
    res["load_average_end"] = __import__("os").getloadavg()
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(res, indent=2, default=str))
        progress(f"wrote {a.json}")
    if a.png:
        progress(f"wrote {a.png}" if plot(res, a.png) else
                 "no chart: none of the sections run (engine, peers, modbus) has one")
    return 0


if __name__ == "__main__":
    sys.exit(main())
