"""softplc side by side with its peers (issue 6), in one table.

  * scan engine vs pyrung: us per scan of the same logic (250 rungs A AND (B OR C) -> Q,
    50 timers + 50 counters, the drawing-table program), target softplc >= 100x faster
  * scan engine vs awlsim: instructions per second, the same boolean / word program as STL
  * Modbus TCP server: FC 3 / FC 16 (10 registers) requests/s, p50/p99, 1 and 8 clients,
    softplc daemon (drawing table, 10 ms period) vs a bare pymodbus server (target
    >= 0.9x) and, when gcc and libmodbus-dev are present, a libmodbus C server (the
    ceiling on this machine)

A peer that is not installed prints "unavailable: <reason>" (make bench installs them).

    .venv/bin/python tools/bench_peers.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from peers import awlsim_peer, libmodbus_peer, modbus_peer, pyrung_peer
from peers.common import print_report, progress, version_of

ROOT = Path(__file__).resolve().parents[1]

DRAWING_IL = ROOT / "ladder_programs" / "drawing_table.il"
TARGET_PYRUNG = 100.0
TARGET_MODBUS = 0.9
SHORT = {"chain250": "250 x A.(B+C)", "timers_counters": "50 TM + 50 C",
         "drawing_table": "drawing table", "boolean": "boolean 1000", "words": "250 word ops"}


def settings(quick: bool) -> dict[str, Any]:
    if quick:
        return {"pyrung": {"scans": 40, "repeat": 2, "warmup": 5},
                "awlsim": {"scans": 100, "repeat": 2, "warmup": 10},
                "modbus": {"duration": 0.5, "max_requests": 50_000, "rounds": 1}}
    return {"pyrung": {"scans": 200, "repeat": 3, "warmup": 20},
            "awlsim": {"scans": 500, "repeat": 3, "warmup": 50},
            "modbus": {"duration": 2.0, "max_requests": 300_000, "rounds": 2}}


def run(quick: bool = False, modbus: bool = True) -> dict[str, Any]:
    s = settings(quick)
    out: dict[str, Any] = {"settings": s}
    progress("peers: pyrung")
    out["pyrung"] = pyrung_peer.run(drawing_table=DRAWING_IL, **s["pyrung"])
    progress("peers: awlsim")
    out["awlsim"] = awlsim_peer.run(**s["awlsim"])
    if modbus:
        cfg = DRAWING_IL.with_suffix(".toml")
        servers = {
            "pymodbus": modbus_peer.pymodbus_server,
            "softplc": lambda: modbus_peer.softplc_server(DRAWING_IL, cfg if cfg.exists()
                                                          else None, "10ms"),
            "libmodbus": libmodbus_peer.LibmodbusServer,
        }
        out["modbus"] = modbus_peer.run(servers, (1, 8), **s["modbus"])
    out["versions"] = {"pyrung": version_of("pyrung"), "awlsim": version_of("awlsim"),
                       "pymodbus": version_of("pymodbus"),
                       "libmodbus": libmodbus_peer.version()}
    return out


def rows(res: dict[str, Any]) -> list[dict[str, Any]]:
    """The one table: case, unit, softplc, peer value, peer, advantage (x), target, met."""
    table: list[dict[str, Any]] = []

    def add(case: str, unit: str, soft: float | None, peer_v: float | None, peer: str,
            adv: float | None, target: float | None = None, note: str = "",
            short: str = "") -> None:
        table.append({"case": case, "short": short or case, "unit": unit, "softplc": soft,
                      "peer_value": peer_v,
                      "peer": peer, "advantage": adv, "target": target,
                      "met": None if target is None or adv is None else adv >= target,
                      "note": note})

    py = res.get("pyrung", {})
    if "unavailable" in py:
        add("pyrung", "", None, None, "pyrung", None, TARGET_PYRUNG,
            "unavailable: " + py["unavailable"])
    else:
        for key in ("chain250", "timers_counters", "drawing_table"):
            r = py.get(key, {})
            if "error" in r:
                add(r.get("label", key), "us/scan", None, None, "pyrung", None, TARGET_PYRUNG,
                    r["error"])
                continue
            note = {True: "outputs agree", False: "OUTPUTS DIFFER"}.get(r["outputs_agree"], "")
            add(f"{r['label']} ({r['instructions']} IL instr)", "us/scan", r["softplc_us"],
                r["pyrung_us"], "pyrung", r["ratio"], TARGET_PYRUNG, note, SHORT[key])
    aw = res.get("awlsim", {})
    if "unavailable" in aw:
        add("awlsim", "", None, None, "awlsim", None, None, "unavailable: " + aw["unavailable"])
    else:
        for key in ("boolean", "words"):
            r = aw.get(key, {})
            if "error" in r:
                add(r.get("label", key), "us/scan", None, None, "awlsim", None, None,
                    r["error"])
                continue
            add(r["label"], "us/scan", r["softplc_us"], r["awlsim_us"], "awlsim", r["ratio"],
                None, short=SHORT[key],
                note=f"Minstr/s: softplc {r['softplc_instr_per_s'] / 1e6:.1f} "
                f"({r['il_instructions']} IL), awlsim {r['awlsim_instr_per_s'] / 1e6:.2f} "
                f"({r['stl_instructions']} STL)")
    mb = res.get("modbus")
    if mb:
        soft = mb.get("softplc", {})
        for peer, target in (("pymodbus", TARGET_MODBUS), ("libmodbus", None)):
            p = mb.get(peer, {})
            if "unavailable" in p or "unavailable" in soft:
                add(f"Modbus server vs {peer}", "req/s", None, None, peer, None, target,
                    "unavailable: " + p.get("unavailable", soft.get("unavailable", "")))
                continue
            for req in ("fc3", "fc16"):
                for n in ("1", "8"):
                    a, b = soft[req][n], p[req][n]
                    add(f"{req.upper()} x10 regs, {n} client{'s' if n != '1' else ''}",
                        "req/s", a["requests_per_s"], b["requests_per_s"], peer,
                        a["requests_per_s"] / b["requests_per_s"] if b["requests_per_s"]
                        else None, target,
                        f"p50/p99 ms: softplc {a['p50_ms']:.3f}/{a['p99_ms']:.3f}, "
                        f"{peer} {b['p50_ms']:.3f}/{b['p99_ms']:.3f}"
                        + (f"; errors {a['errors']}/{b['errors']}"
                           if a["errors"] or b["errors"] else ""))
    return table


def _fmt(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:,.0f}" if v >= 1000 else f"{v:.2f}"


def report(res: dict[str, Any]) -> str:
    v = res.get("versions", {})
    lines = ["Peers: " + ", ".join(f"{k} {v[k] or 'not installed'}" for k in v),
             "advantage = peer time / softplc time, or softplc rate / peer rate"]
    hdr = (f"{'case':52}{'unit':>9}{'softplc':>11}{'peer':>11}  {'peer name':10}"
           f"{'advantage':>10}{'target':>8}  met")
    lines += [hdr, "-" * len(hdr)]
    for r in rows(res):
        met = "-" if r["met"] is None else ("yes" if r["met"] else "NO")
        tgt = f">= {r['target']:g}" if r["target"] else "-"
        adv = f"{r['advantage']:.2f}x" if r["advantage"] is not None else "-"
        lines.append(f"{r['case'][:52]:52}{r['unit']:>9}{_fmt(r['softplc']):>11}"
                     f"{_fmt(r['peer_value']):>11}  {r['peer']:10}{adv:>10}{tgt:>8}  {met}")
        if r["note"]:
            lines.append(f"{'':4}{r['note']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer scans, shorter Modbus load")
    ap.add_argument("--no-modbus", action="store_true", help="skip the Modbus servers")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON here")
    a = ap.parse_args(argv)
    res = run(a.quick, modbus=not a.no_modbus)
    print_report(report(res), res, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
