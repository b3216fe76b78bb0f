"""The test zygote (tests/zygote.py): a forked `softplc` command line answers as `python -m
softplc` does, since every end-to-end daemon is started that way."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

from daemon_util import ROOT, Daemon
from waits import WAIT_S
from zygote import forking, popen

# an environment larger than one read of the zygote's socket, so that the request comes in
# chunks (execve takes at most 128 KiB per variable: several)
BIG_VARS, BIG_VAR_CHARS = 4, 100_000


def test_a_refused_start_is_the_same_forked_and_as_python_m_softplc(tmp_path):
    argv = ["run", str(tmp_path / "missing.il"), "--port", "0", "--web", "off"]
    env = dict(os.environ, PYTHONPATH=str(ROOT),
               **{f"SOFTPLC_BIG{i}": "x" * BIG_VAR_CHARS for i in range(BIG_VARS)})
    forked = popen(argv, tmp_path, env)
    assert forking() == (not isinstance(forked, subprocess.Popen))
    rc = forked.wait(WAIT_S)
    err = forked.stderr.read()
    plain = subprocess.run([sys.executable, "-m", "softplc", *argv], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=WAIT_S)
    assert (rc, err) == (plain.returncode, plain.stderr)
    assert rc == 1 and "missing.il" in err and "Traceback" not in err


def test_ctrl_c_stops_a_forked_daemon_and_a_kill_is_reported_as_popen_does(tmp_path):
    d = Daemon(tmp_path, program="LD 1\nST %Q0.0\n")
    assert d.stop() == 0  # SIGINT: the daemon's own clean stop
    d.wait_for("stopped after")
    d = Daemon(tmp_path, program="LD 1\nST %Q0.0\n")
    d.proc.kill()
    assert d.proc.wait(WAIT_S) == -signal.SIGKILL
    d.proc.send_signal(signal.SIGINT)  # after its end: nothing, as Popen
