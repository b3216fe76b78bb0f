"""`softplc` command lines for the end-to-end tests, forked from one pre-imported process.

A `python -m softplc run` spends about 1 s of CPU importing (numpy, pydantic's
configuration models, asyncio, the compiler) before its first scan, and the end-to-end tier
starts about a hundred daemons: on the 2-core CI machine that alone was a minute and a half
of the suite. So each test worker starts one *zygote* the first time it needs a daemon: a
Python process that imports what `softplc run` (with its web monitor) imports, then waits.
Each daemon is a fork of it that runs its command line as `python -m softplc` does
(softplc/__main__.py), with the test's own stdio pipes, folder, environment and signal
dispositions; the process the test holds behaves as a `subprocess.Popen` does (pid, stdout,
stderr, poll, wait, send_signal, kill, returncode). `softplc plant up` starts its daemons
the same way (softplc/plant/hosts.py `_start`).

What a fork does not show, the tests that start `python -m softplc` themselves keep
covering (the interpreter's start, `-m`, the console script). `SOFTPLC_TEST_FORK=0` starts
every daemon as a plain subprocess instead.
"""

from __future__ import annotations

import atexit
import gc
import io
import json
import os
import selectors
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path
from typing import IO, Any

ROOT = Path(__file__).resolve().parents[1]
# a request: {"argv", "cwd", "env"} with the child's stdin, stdout and stderr as fds
MAX_REQUEST_BYTES = 1 << 20
STDIO_FDS = 3
# how long a test waits for the zygote to say it forked (it only forks: a loaded machine)
REPLY_TIMEOUT_S = 60.0


# -- the zygote (its own process) ---------------------------------------------------------
def _child(argv: list[str], cwd: str, env: dict[str, str], fds: list[int]) -> None:
    """In the forked child: become `python -m softplc ARGV` in `cwd` with `env`, as
    `softplc plant up`'s daemons do (`run_forked`); never returns."""
    from softplc.plant.hosts import run_forked

    def setup() -> None:
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        os.closerange(STDIO_FDS, os.sysconf("SC_OPEN_MAX"))  # as Popen's close_fds
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)  # Ctrl-C as in a new python
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update(env)
        _stdio(bool(env.get("PYTHONUNBUFFERED")))
        if env.get("PYTHONFAULTHANDLER"):
            import faulthandler

            faulthandler.enable()

    run_forked(argv, setup)


def _stdio(unbuffered: bool) -> None:
    """sys.stdout and sys.stderr on fds 1 and 2 as a new interpreter makes them for pipes
    (block-buffered stdout unless PYTHONUNBUFFERED; line-buffered stderr)."""
    def stream(fd: int, **kw: Any) -> io.TextIOWrapper:
        raw = io.FileIO(fd, "w", closefd=False)
        return io.TextIOWrapper(raw if unbuffered else io.BufferedWriter(raw),
                                encoding=sys.stdout.encoding, write_through=unbuffered, **kw)

    sys.stdout = sys.__stdout__ = stream(1)
    sys.stderr = sys.__stderr__ = stream(2, errors="backslashreplace", line_buffering=True)


def _send(sock: socket.socket, msg: dict[str, Any]) -> None:
    sock.sendall(json.dumps(msg).encode() + b"\n")


def serve(fd: int) -> None:
    """The zygote: import, then fork a child per request on socket `fd` and report each
    child's exit; at the socket's end (the test worker gone) kill what is left."""
    from softplc.commands.plant import preload

    preload()
    # what the children share stays out of their collector's walks (and their pages stay
    # shared: a collection writes to every object it walks), as in a pre-fork server
    gc.collect()
    gc.freeze()
    sock = socket.socket(fileno=fd)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    signal.signal(signal.SIGCHLD, lambda *_: None)  # a handler, so the wake-up fd is written
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the worker's Ctrl-C is not the zygote's
    children: set[int] = set()
    sel = selectors.DefaultSelector()
    sel.register(sock, selectors.EVENT_READ)
    sel.register(wake_r, selectors.EVENT_READ)
    buf = b""
    pending: list[int] = []  # the stdio fds of the request being read (its first chunk's)
    while True:
        for key, _ in sel.select():
            if key.fileobj == wake_r:
                os.read(wake_r, 4096)
                _reap(sock, children)
                continue
            data, fds, _flags, _addr = socket.recv_fds(sock, MAX_REQUEST_BYTES, STDIO_FDS)
            if not data:
                for pid in children:
                    os.kill(pid, signal.SIGKILL)
                # skip the interpreter's teardown of everything PRELOAD imported (about 1 s,
                # which the worker's exit waits for): nothing else is left to close
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(0)
            buf += data
            pending += fds
            if b"\n" not in buf:  # a request may come in several chunks
                continue
            line, _, buf = buf.partition(b"\n")
            req, fds, pending = json.loads(line), pending, []
            sys.stdout.flush()
            sys.stderr.flush()
            pid = os.fork()
            if pid == 0:
                sock.close()
                _child(req["argv"], req["cwd"], req["env"], fds)
            for f in fds:
                os.close(f)
            children.add(pid)
            _send(sock, {"pid": pid})


def _reap(sock: socket.socket, children: set[int]) -> None:
    while children:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        children.discard(pid)
        _send(sock, {"exit": pid, "rc": os.waitstatus_to_exitcode(status)})


# -- the test's side --------------------------------------------------------------------
class Zygote:
    """One per test worker: started at the first request."""

    def __init__(self) -> None:
        ours, theirs = socket.socketpair()
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(ROOT), str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]))
        self.proc = subprocess.Popen(
            [sys.executable, "-c", f"import zygote; zygote.serve({theirs.fileno()})"],
            pass_fds=[theirs.fileno()], env=env, stdin=subprocess.DEVNULL)
        theirs.close()
        self.sock = ours
        self.lock = threading.Lock()  # one request at a time
        self.changed = threading.Condition()
        self.replies: list[int] = []
        self.exits: dict[int, int] = {}
        threading.Thread(target=self._read, name="zygote", daemon=True).start()
        atexit.register(self.close)

    def close(self) -> None:
        """The worker's end: the zygote kills what is left of its children and exits."""
        try:
            self.sock.shutdown(socket.SHUT_RDWR)  # its end of the socket sees the end
        except OSError:
            pass
        self.sock.close()
        try:
            self.proc.wait(REPLY_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()

    def _read(self) -> None:
        for line in self.sock.makefile("rb"):
            msg = json.loads(line)
            with self.changed:
                if "exit" in msg:
                    self.exits[msg["exit"]] = msg["rc"]
                else:
                    self.replies.append(msg["pid"])
                self.changed.notify_all()
        with self.changed:  # the zygote is gone: no more exits will come
            self.replies.append(-1)
            self.changed.notify_all()

    def fork(self, argv: list[str], cwd: Path, env: dict[str, str],
             fds: list[int]) -> int:
        req = json.dumps({"argv": argv, "cwd": str(cwd), "env": env}).encode() + b"\n"
        with self.lock:
            sent = socket.send_fds(self.sock, [req], fds)  # one sendmsg: may be short
            self.sock.sendall(req[sent:])
            with self.changed:
                if not self.changed.wait_for(lambda: self.replies, REPLY_TIMEOUT_S):
                    raise RuntimeError("the test zygote did not fork in time")
                pid = self.replies.pop(0)
        if pid < 0:
            raise RuntimeError("the test zygote has exited")
        return pid

    def wait(self, pid: int, timeout: float | None) -> int | None:
        with self.changed:
            self.changed.wait_for(lambda: pid in self.exits, timeout)
            return self.exits.get(pid)


_zygote: Zygote | None = None
_zygote_lock = threading.Lock()


def zygote() -> Zygote:
    global _zygote
    with _zygote_lock:
        if _zygote is None or _zygote.proc.poll() is not None:
            _zygote = Zygote()
        return _zygote


def forking() -> bool:
    return os.environ.get("SOFTPLC_TEST_FORK", "1") != "0" and hasattr(os, "fork")


class Forked:
    """A `softplc` command line forked by the zygote, with `subprocess.Popen`'s interface
    as far as the tests use it (stdout and stderr pipes, text)."""

    def __init__(self, argv: list[str], cwd: Path, env: dict[str, str]):
        self.args = [sys.executable, "-m", "softplc", *argv]
        out_r, out_w = os.pipe()
        err_r, err_w = os.pipe()
        null = os.open(os.devnull, os.O_RDONLY)
        self._zygote = zygote()
        try:
            self.pid = self._zygote.fork(argv, cwd, env, [null, out_w, err_w])
        finally:
            for fd in (null, out_w, err_w):
                os.close(fd)
        self.stdout: IO[str] = open(out_r, encoding="utf-8", errors="replace")
        self.stderr: IO[str] = open(err_r, encoding="utf-8", errors="replace")
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self._zygote.wait(self.pid, 0)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None:
            self.returncode = self._zygote.wait(self.pid, timeout)
            if self.returncode is None:
                raise subprocess.TimeoutExpired(self.args, timeout or 0)
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:  # never a signal to a pid that may be someone else's now
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:  # it ended, its exit not yet reported (as Popen)
                pass

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def popen(argv: list[str], cwd: Path, env: dict[str, str]) -> Forked | subprocess.Popen:
    """`python -m softplc ARGV` with stdout and stderr pipes (text), forked from the zygote
    unless SOFTPLC_TEST_FORK=0."""
    if forking():
        return Forked(argv, cwd, env)
    return subprocess.Popen([sys.executable, "-m", "softplc", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, cwd=cwd,
                            preexec_fn=default_sigint)


def default_sigint() -> None:
    """`preexec_fn` of a child the test interrupts with SIGINT (Ctrl-C): the default
    disposition, whatever the suite inherited (a shell's background job, CI, starts with
    SIGINT ignored, and Python then raises no KeyboardInterrupt in the child)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
