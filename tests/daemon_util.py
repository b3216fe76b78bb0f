"""`python -m softplc run` on a free loopback port, for end-to-end tests (forked from the
test zygote: tests/zygote.py)."""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
from waits import WAIT_S
from zygote import ROOT, popen

from softplc.modbus.rawclient import RawClient

# How long a daemon may take to print its banner: generous, as the wait ends at the line
# (a loaded machine starts Python slowly; the test must not depend on its speed).
START_TIMEOUT_S = 90.0
# Every daemon started by a test: the session's end kills any still running (a test that
# failed before its fixture could stop it must not leave a `--speed max` daemon burning a
# core under the rest of the suite).
LIVE: set = set()  # subprocess.Popen or zygote.Forked


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
        # PYTHONFAULTHANDLER: a daemon that does not stop is sent SIGABRT and prints every
        # thread's stack (`stop`), so a hang says where it hangs
        env = dict(os.environ, PYTHONFAULTHANDLER="1", PYTHONPATH=str(ROOT) + os.pathsep
                   + os.environ.get("PYTHONPATH", ""))
        # forked from a pre-imported process (tests/zygote.py), SIGINT as in a new python
        self.proc = popen(["run", str(prog), "--port", "0", *args], tmp, env)
        LIVE.add(self.proc)
        self.lines: queue.Queue[str] = queue.Queue()
        self.out: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()
        # stderr is drained as it comes: a daemon whose unread pipe filled up (64 KiB of
        # warnings) would block on its next write, and then not even stop
        self._err: list[str] = []
        self._err_changed = threading.Condition()
        self._err_reader = threading.Thread(target=self._read_err, daemon=True)
        self._err_reader.start()
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

    def _read_err(self) -> None:
        for line in self.proc.stderr:  # type: ignore[union-attr]
            with self._err_changed:
                self._err.append(line)
                self._err_changed.notify_all()

    def stderr(self) -> str:
        """All the daemon's stderr: after it exited, the whole of it."""
        if self.proc.poll() is not None:
            self._err_reader.join(10)
        with self._err_changed:
            return "".join(self._err)

    def stderr_until(self, text: str, timeout: float = WAIT_S) -> str:
        """The daemon's stderr so far, once it contains `text` (read while it runs)."""
        with self._err_changed:
            if not self._err_changed.wait_for(lambda: text in "".join(self._err), timeout):
                raise AssertionError(f"no {text!r} in stderr: {''.join(self._err)}")
            return "".join(self._err)

    def wait_for(self, pattern: str, timeout: float = WAIT_S) -> str:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                line = self.lines.get(timeout=max(0.01, end - time.monotonic()))
            except queue.Empty:
                break
            if line == "":
                raise AssertionError(f"daemon exited; output: {''.join(self.out)}; "
                                     f"stderr: {self.stderr()}")
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
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.send_signal(signal.SIGABRT)  # faulthandler: every thread's stack
            self.proc.wait(10)
            raise AssertionError(f"the daemon did not stop within {timeout:g} s of signal "
                                 f"{sig}; its output: {''.join(self.out)}; stderr: "
                                 f"{self.stderr()[-20000:]}") from None

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
