"""`python -m softplc run` as a subprocess on a free loopback port, for end-to-end tests."""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from waits import WAIT_S

from softplc.modbus.rawclient import RawClient

ROOT = Path(__file__).resolve().parents[1]

# How long a daemon may take to print its banner: generous, as the wait ends at the line
# (a loaded machine starts Python slowly; the test must not depend on its speed).
START_TIMEOUT_S = 90.0
# Every daemon started by a test: the session's end kills any still running (a test that
# failed before its fixture could stop it must not leave a `--speed max` daemon burning a
# core under the rest of the suite).
LIVE: set[subprocess.Popen] = set()


def kill_all() -> None:
    for proc in list(LIVE):
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    LIVE.clear()


class Daemon:
    """`python -m softplc run` on a free port; stdout lines collected by a thread."""

    def __init__(self, tmp: Path, *args: str, program: str | Path = "", wait: bool = True):
        if isinstance(program, Path):  # an existing program file
            prog = program
        else:
            prog = tmp / "prog.il"
            prog.write_text(program)
        if "--web" not in args:  # no web monitor unless the test asks (a faster start, and
            args = (*args, "--web", "off")  # no daemon on the default port 8020)
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get(
            "PYTHONPATH", ""))
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "softplc", "run", str(prog), "--port", "0", *args],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp,
            preexec_fn=default_sigint)  # `stop()` sends SIGINT: it must not be ignored
        LIVE.add(self.proc)
        self.lines: queue.Queue[str] = queue.Queue()
        self.out: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()
        self.port = 0
        if wait:
            try:
                self.wait_listening()
            except BaseException:
                self.kill()  # no caller holds it yet: nobody else would
                raise

    def wait_listening(self) -> int:
        """Wait for the banner's address line (`wait=False` starts several daemons at once,
        overlapping their start-up); the port."""
        line = self.wait_for(r"listening on 127\.0\.0\.1:(\d+)", START_TIMEOUT_S)
        self.port = int(re.search(r":(\d+)$", line.strip())[1])
        return self.port

    def _read(self) -> None:
        for line in self.proc.stdout:  # type: ignore[union-attr]
            self.lines.put(line)
        self.lines.put("")

    def wait_for(self, pattern: str, timeout: float = WAIT_S) -> str:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                line = self.lines.get(timeout=max(0.01, end - time.monotonic()))
            except queue.Empty:
                break
            if line == "":
                raise AssertionError(f"daemon exited; output: {''.join(self.out)}; "
                                     f"stderr: {self.proc.stderr.read()}")  # type: ignore
            self.out.append(line)
            if re.search(pattern, line):
                return line
        raise AssertionError(f"no line matching {pattern!r} in {''.join(self.out)}")

    def web_port(self) -> int:
        """The port of the web monitor, from the banner's `web monitor on URL` line (read
        before the address line that `wait_listening` waits for)."""
        line = next(x for x in self.out if "web monitor on" in x)
        return int(re.search(r":(\d+)/", line)[1])

    def client(self) -> RawClient:
        return RawClient("127.0.0.1", self.port, timeout=5)

    def stop(self, sig: int = signal.SIGINT, timeout: float = WAIT_S) -> int:
        self.proc.send_signal(sig)
        return self.proc.wait(timeout)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)
        LIVE.discard(self.proc)


@pytest.fixture
def daemons():
    """Daemons a test starts (`started(daemons, ...)`); killed at the end if still running."""
    started: list[Daemon] = []
    yield started
    for d in started:
        d.kill()


def started(daemons: list[Daemon], tmp: Path, *args: str, **kw) -> Daemon:
    d = Daemon(tmp, *args, **kw)
    daemons.append(d)
    return d


def default_sigint() -> None:
    """`preexec_fn` of a child the test interrupts with SIGINT (Ctrl-C): the default
    disposition, whatever the suite inherited (a shell's background job, CI, starts with
    SIGINT ignored, and Python then raises no KeyboardInterrupt in the child)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
