"""kill -9 benchmark of `softplc run --state`: are acknowledged writes kept?

Loop: start the daemon on a state file, let writer threads hammer it (each writer has its
own pair of registers and writes an increasing 32-bit counter with FC 16, remembering the
last value the daemon acknowledged), `kill -9` the daemon at a random moment with writes
in flight, restart it on the same file and read the registers back. A register holding
less than its last acknowledged value lost acknowledged writes (the difference). Also
counted: files left in the state file's directory besides the program, the state and the
program kept with it (`softplc.persist.kept`).

`--attack delete` (or `replace`) also deletes the state file (or renames another file over
it) while the writes go on, 0.2-0.6 s before the kill; the daemon must re-create it with
every acknowledged write (issue 21). `--signal term` stops the daemon with SIGTERM instead.

    .venv/bin/python tools/bench_kill.py [--kills 100] [--writers 4] [--attack delete]
"""

from __future__ import annotations

import argparse
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from softplc.modbus.rawclient import RawClient
from softplc.persist.kept import path_of

ROOT = Path(__file__).resolve().parents[1]

PROGRAM = "LD 1\n[ %MW0 := %MW0 + 1 ]\nEND\n"
BASE = 100  # writer i owns %MW(BASE + 2i) (high word) and %MW(BASE + 2i + 1) (low word)


# How a daemon is started: `softplc` command-line arguments and a folder -> a process with
# text stdout and stderr pipes (`subprocess.Popen`'s interface). The test suite passes its
# own (tests/zygote.py: forked from a pre-imported process).
Launch = Callable[[list[str], Path], Any]


def python_m_softplc(argv: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "softplc", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=cwd)


def start_daemon(program: Path, state: Path, save_interval: str,
                 launch: Launch = python_m_softplc) -> tuple[Any, int]:
    proc = launch(["run", str(program), "--port", "0", "--state", str(state),
                   "--save-interval", save_interval, "--stats-interval", "0",
                   "--rt-priority", "0", "--web", "off"], program.parent)
    for line in proc.stdout:  # type: ignore[union-attr]
        m = re.search(r"listening on [\d.]+:(\d+)", line)
        if m:
            threading.Thread(target=proc.stdout.read, daemon=True).start()  # type: ignore
            return proc, int(m[1])
    raise RuntimeError("daemon did not start: " + proc.stderr.read())  # type: ignore


def _writer(port: int, i: int, start: int, acked: list[int], stop: threading.Event) -> None:
    try:
        with RawClient("127.0.0.1", port, timeout=2) as c:
            k = start
            while not stop.is_set():
                k += 1
                c.write_registers(BASE + 2 * i, [(k >> 16) & 0xFFFF, k & 0xFFFF])
                acked[i] = k  # only once the daemon has answered
    except (OSError, ConnectionError):
        pass  # killed under us


def _read_counters(port: int, writers: int) -> list[int]:
    with RawClient("127.0.0.1", port, timeout=5) as c:
        regs = c.read_registers(BASE, 2 * writers)
    return [(regs[2 * i] << 16) | regs[2 * i + 1] for i in range(writers)]


def _attack(state: Path, attack: str) -> None:
    if attack == "delete":
        state.unlink()
    elif attack == "replace":  # e.g. a backup restored, an editor's save
        other = state.with_name("other.tmp")
        other.write_bytes(b"not the daemon's state")
        os.replace(other, state)


def run(kills: int = 100, writers: int = 4, save_interval: str = "0.5s",
        seed: int = 1, progress: bool = False, attack: str = "none",
        sig: signal.Signals = signal.SIGKILL, launch: Launch = python_m_softplc
        ) -> dict[str, object]:
    rng = random.Random(seed)
    lost: list[int] = []
    acked_total = 0
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "bench.il"
        program.write_text(PROGRAM)
        state = Path(tmp) / "plc.state"
        proc, port = start_daemon(program, state, save_interval, launch)
        counters = [0] * writers
        t0 = time.monotonic()
        try:
            for n in range(kills):
                acked = list(counters)
                stop = threading.Event()
                threads = [threading.Thread(target=_writer, args=(port, i, counters[i], acked,
                                                                  stop)) for i in range(writers)]
                for t in threads:
                    t.start()
                if attack != "none":
                    time.sleep(rng.uniform(0.1, 0.3))
                    _attack(state, attack)
                time.sleep(rng.uniform(0.2, 0.6))
                proc.send_signal(sig)  # writes in flight
                proc.wait(10)
                stop.set()
                for t in threads:
                    t.join()
                acked_total += sum(a - c for a, c in zip(acked, counters, strict=True))
                proc, port = start_daemon(program, state, save_interval, launch)
                restored = _read_counters(port, writers)
                lost.append(sum(max(0, a - r) for a, r in zip(acked, restored, strict=True)))
                counters = [max(a, r) for a, r in zip(acked, restored, strict=True)]
                if progress:
                    done = n + 1
                    eta = (time.monotonic() - t0) / done * (kills - done)
                    print(f"\rkill {done}/{kills}, lost so far {sum(lost)}, "
                          f"ETA {eta:.0f} s   ", end="", file=sys.stderr, flush=True)
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(10)
            if progress:
                print(file=sys.stderr)
        leftovers = sorted(p.name for p in Path(tmp).iterdir()
                           if p.name not in (program.name, state.name, path_of(state).name))
    return {"kills": kills, "attack": attack, "acknowledged_writes": acked_total,
            "lost_total": sum(lost), "lost_mean": statistics.mean(lost) if lost else 0.0,
            "lost_max": max(lost, default=0), "kills_with_loss": sum(1 for x in lost if x),
            "leftover_files": leftovers}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kills", type=int, default=100)
    ap.add_argument("--writers", type=int, default=4)
    ap.add_argument("--save-interval", default="0.5s", help="the daemon's --save-interval")
    ap.add_argument("--attack", choices=["none", "delete", "replace"], default="none",
                    help="delete or replace the state file 0.2-0.6 s before each kill")
    ap.add_argument("--signal", choices=["kill", "term"], default="kill",
                    help="SIGKILL (default) or SIGTERM")
    a = ap.parse_args(argv)
    sig = signal.SIGKILL if a.signal == "kill" else signal.SIGTERM
    r = run(a.kills, a.writers, a.save_interval, progress=True, attack=a.attack, sig=sig)
    print(f"{r['kills']} {'kill -9' if a.signal == 'kill' else 'SIGTERM'} with {a.writers} "
          f"writers in flight, save interval {a.save_interval}, attack {a.attack}")
    for k, v in r.items():
        print(f"  {k:22} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
