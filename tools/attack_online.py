"""Round 3's online-change attacks (issue 31 items 1 and 2) against a real `softplc run`.

`files`: POST /api/program with configurations naming /etc/passwd, /dev/zero, a FIFO
nobody writes, `../../etc/passwd` and a symbolic link out; for each the HTTP status, the
answer's time, whether the file's content came back, the daemon's resident memory; then a
valid change (must apply: nothing wedged).

`restart`: `softplc run P.il --state S`, `softplc load NEW.il`, a host writes %MW11, kill -9,
the same command line again; N rounds: how many ran NEW, warm, with %MW11 as written.

    .venv/bin/python tools/attack_online.py files
    .venv/bin/python tools/attack_online.py restart [--rounds 10]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

from softplc.modbus.rawclient import RawClient

ROOT = Path(__file__).resolve().parents[1]
STAR = ROOT / "ladder_programs" / "star_delta.il"
P = "LD 1\n[ %MW12 := %MW12 + 1 ]\n[ %MW10 := 1 ]\nEND\n"
NEW = "LD 1\n[ %MW12 := %MW12 + 1 ]\n[ %MW10 := 2 ]\nEND\n"
SCANS = 5  # scans to wait (%MW12 counts them) after %MW10 is cleared


def start(program: Path, *args: str) -> tuple[subprocess.Popen, int, int]:
    """A daemon with a web monitor on free ports: (process, Modbus port, web port)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "softplc", "run", str(program), "--port", "0", "--web", "0",
         "--stats-interval", "0", "--rt-priority", "0", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=program.parent)
    web = 0
    for line in proc.stdout:  # type: ignore[union-attr]
        if m := re.search(r"web monitor on http://[\d.]+:(\d+)/", line):
            web = int(m[1])
        if m := re.search(r"listening on [\d.]+:(\d+)", line):
            threading.Thread(target=proc.stdout.read, daemon=True).start()  # type: ignore
            return proc, int(m[1]), web
    raise RuntimeError("daemon did not start: " + proc.stderr.read())  # type: ignore


def post(web: int, body: dict) -> tuple[int, str, float]:
    req = urllib.request.Request(f"http://127.0.0.1:{web}/api/program",
                                 json.dumps(body).encode(),
                                 {"Content-Type": "application/json"})
    t0 = time.monotonic()
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, r.read().decode(), time.monotonic() - t0
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(), time.monotonic() - t0


def rss_kb(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def files() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        config = STAR.with_suffix(".toml").read_text()
        os.mkfifo(t / "pipe.csv")
        (t / "out.csv").symlink_to("/etc/passwd")
        proc, _, web = start(STAR, "--config", str(STAR.with_suffix(".toml")),
                             "--config-dir", str(t))
        try:
            print(f"{'symbols_file':24} {'HTTP':>4} {'ms':>7} {'content?':>8} {'RSS kB':>8}")
            for name in ("/etc/passwd", "/dev/zero", "pipe.csv", "../../etc/passwd",
                         "out.csv"):
                cfg = config.replace('"star_delta_symbols.csv"', json.dumps(name))
                status, text, dt = post(web, {"program": STAR.read_text(), "config": cfg})
                leaked = "root:" in text
                print(f"{name:24} {status:>4} {dt * 1000:>7.1f} {str(leaked):>8} "
                      f"{rss_kb(proc.pid):>8}")
            status, text, dt = post(web, {"program": STAR.read_text()})
            print(f"then a valid change: HTTP {status}, applied "
                  f"{json.loads(text).get('applied')}, {dt * 1000:.1f} ms")
        finally:
            proc.terminate()
            proc.wait(10)
    return 0


def restart(rounds: int) -> int:
    good = 0
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        prog, new = t / "P.il", t / "NEW.il"
        args = ("--state", str(t / "S"))
        for n in range(rounds):
            prog.write_text(P)
            new.write_text(NEW.replace("%MW10 := 2", f"%MW10 := {n + 2}"))
            proc, port, web = start(prog, *args)
            subprocess.run([sys.executable, "-m", "softplc", "load", str(new), "--port",
                            str(web), "--yes"], check=True, capture_output=True)
            with RawClient("127.0.0.1", port, timeout=5) as c:
                c.write_registers(11, [700 + n])
                while c.read_registers(10, 1) != [n + 2]:
                    time.sleep(0.01)
            proc.kill()
            proc.wait(10)
            proc, port, _ = start(prog, *args)  # the original command line
            with RawClient("127.0.0.1", port, timeout=5) as c:
                mw11 = c.read_registers(11, 1)[0]
                c.write_registers(10, [0])  # which program runs writes it again
                scans = c.read_registers(12, 1)[0]
                while c.read_registers(12, 1)[0] < scans + SCANS:
                    time.sleep(0.01)
                mw10 = c.read_registers(10, 1)[0]
            proc.terminate()
            proc.wait(10)
            ok = (mw10, mw11) == (n + 2, 700 + n)
            good += ok
            print(f"round {n + 1}: %MW10 = {mw10} (NEW: {n + 2}), %MW11 = {mw11} "
                  f"(written: {700 + n}) {'ok' if ok else 'LOST'}")
            (t / "S").unlink()
    print(f"{good} of {rounds} restarts ran the loaded program with its data")
    return 0 if good == rounds else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("attack", choices=["files", "restart"])
    ap.add_argument("--rounds", type=int, default=10)
    a = ap.parse_args(argv)
    return files() if a.attack == "files" else restart(a.rounds)


if __name__ == "__main__":
    sys.exit(main())
