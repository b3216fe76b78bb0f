"""Issue 14 through the daemon (`softplc run --speed max`, loopback Modbus): the recorder's
files do not depend on host timing, and a host timeout or a host refusal leaves the
parameters (the parameter file and the active words) unchanged, reports the fault
(`%MW470`: 4 timeout, 3 refused) and restores the acceleration limit. The red lamp of the
FAULT step is checked through the PLC API (test_mass_tuning_program.py): %Q is not on the
Modbus map.

The PLC-API tests' short geometry (4-6 mm moves, 10 ms dwells: under 2 s of machine time
per run) keeps this module short; the estimate itself runs through the daemon in
test_mass_tuning_e2e.py.

Why the files are identical although the softkey arrives at any scan: PLC time advances by
the scan period per scan (virtual clock), the axis rests at a fixed point before the first
run (the same bits whatever scan the softkey arrives at: checked here), timers count from
their own start and the recorder samples from its START; the host's requests only come
after both files are stored. Two runs in ONE daemon differ in a few torque LSBs: the second
starts from the state the first left (the position integrator), as on a real axis."""

from __future__ import annotations

import re
import threading
import time
from pathlib import Path

from daemon_util import Daemon

from softplc.cli import main
from softplc.errors import MassFileError
from softplc.massest import handshake, tuning
from softplc.modbus.host import ModbusHost

ROOT = Path(__file__).resolve().parents[1]
IL = ROOT / "ladder_programs" / "mass_tuning.il"
TOML = ROOT / "ladder_programs" / "mass_tuning.toml"
SHORT = {"%KD0": -3000, "%KD2": 3000, "%KD4": -2000, "%KD6": 2000, "%KD8": 0,
         "%KW10": 600, "%KW11": 1200, "%KW12": 1200}  # as test_mass_tuning_program.py
SOFTKEY, RESET, AUTO = 200, 203, 205  # %M bits
IDLE, REQUEST_WAIT, FAULT = 0, 29, 40
W_FAULT, F_ACC_LIMIT, F_ACTIVE_MPS, W_ROW_APPLIED, W_APPLIED = 470, 300, 500, 496, 498
FILES = (tuning.CAL_FILE, tuning.MEAS_FILE)


def short_toml(path: Path, host_timeout_s: int) -> Path:
    text = TOML.read_text(encoding="utf-8")
    for key, value in SHORT.items():
        text, n = re.subn(rf'^"{key}" = \S+', f'"{key}" = {value}', text, flags=re.M)
        assert n == 1, key
    text, n = re.subn(r'^("%TM[0-9]") = \{.*\}', r'\1 = { base = "10ms", preset = 1 }', text,
                      flags=re.M)
    assert n == 10
    text, n = re.subn(r'^"%TM10" = \{.*\}',
                      f'"%TM10" = {{ base = "1s", preset = {host_timeout_s} }}', text,
                      flags=re.M)
    assert n == 1
    path.write_text(text, encoding="utf-8")
    return path


def wait_step(h: ModbusHost, step: int, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while (now := h.read_words(handshake.W_STATE, 1)[0]) != step:
        assert time.monotonic() < end, f"step {now}, not {step}"
        time.sleep(0.01)


def parameters(h: ModbusHost, directory: Path) -> tuple[object, ...]:
    """What a failed estimation must leave alone: the parameter file and the PLC's active
    parameter words (22 MPs as float32, row applied, count of applications)."""
    out = directory / tuning.OUTPUT_FILE
    return (out.read_bytes(), out.stat().st_mtime_ns, h.read_words(F_ACTIVE_MPS, 44),
            h.read_words(W_ROW_APPLIED, 3))


def measure(h: ModbusHost, directory: Path) -> list[bytes]:
    """Press the softkey, wait for the request; the two recordings, written in this run."""
    stamps = [(directory / f).stat().st_mtime_ns if (directory / f).exists() else 0
              for f in FILES]
    h.write_bit(SOFTKEY, True)
    wait_step(h, REQUEST_WAIT)
    assert h.read_float(F_ACC_LIMIT) == 1.0  # restored at the park move, before the request
    assert [(directory / f).stat().st_mtime_ns for f in FILES] != stamps
    return [(directory / f).read_bytes() for f in FILES]


def fault(h: ModbusHost) -> tuple[int, float]:
    """In the FAULT step: the fault code and ACC_LIMIT."""
    wait_step(h, FAULT)
    return h.read_words(W_FAULT, 1)[0], h.read_float(F_ACC_LIMIT)


def reset(h: ModbusHost) -> None:
    h.write_bit(RESET, True)
    wait_step(h, IDLE)


def machine(directory: Path, host_timeout_s: int) -> Path:
    """A directory with the host's files (settings, template, the parameters in force) and
    the short-geometry configuration; the recorder writes its files there."""
    directory.mkdir()
    paths = tuning.write_example(directory, geometry="macro")
    for f in FILES:
        (directory / f).unlink()  # the recorder writes them
    (directory / tuning.OUTPUT_FILE).write_bytes(paths["template"].read_bytes())
    return short_toml(directory / "machine.toml", host_timeout_s)


def start(directory: Path, host_timeout_s: int) -> Daemon:
    return Daemon(directory, "--config", str(machine(directory, host_timeout_s)), "--speed",
                  "max", "--stats-interval", "0", program=IL, wait=False)


def session(daemon: Daemon, directory: Path, rest: float, answer: bool
            ) -> tuple[list[bytes], int]:
    """The softkey pressed `rest` wall seconds after the daemon is up; `softplc tune --once`
    answering if `answer`. Checks the fault and that the parameters did not change; returns
    the recordings and the host's status word."""
    port = daemon.wait_listening()
    rc: list[int] = []
    host = threading.Thread(target=lambda: rc.append(main(
        ["tune", "--dir", str(directory), "--port", str(port), "--once", "--wait", "60",
         "--poll", "0.01"])))
    with ModbusHost("127.0.0.1", port) as h:
        h.write_bit(AUTO, True)
        before = parameters(h, directory)
        time.sleep(rest)
        if answer:
            host.start()
        files = measure(h, directory)
        if answer:
            host.join(60)
            assert rc == [1]  # refused
        code = fault(h)
        status = h.read_words(handshake.W_STATUS, 1)[0]
        assert parameters(h, directory) == before
        reset(h)
        assert h.read_words(W_FAULT, 1) == [code[0]]  # kept until the next run
    assert daemon.stop() == 0
    assert code == ((3 if answer else 4), 1.0)  # fault code, ACC_LIMIT restored
    return files, status


def test_timeout_and_refusal_leave_the_parameters_and_the_files_repeat(tmp_path, capsys):
    # two daemons started together (their start-ups overlap)
    quiet = start(tmp_path / "a", host_timeout_s=2)  # no host: timeout after 2 s
    refusing = start(tmp_path / "b", host_timeout_s=120)  # the host answers first
    try:
        first, _ = session(quiet, tmp_path / "a", 0.0, answer=False)
        # the host refuses: the short moves leave the settings' measurement range (a
        # recording that does not fit the settings file); pressed thousands of scans later
        second, status = session(refusing, tmp_path / "b", 0.3, answer=True)
    finally:
        quiet.kill()
        refusing.kill()
    err = capsys.readouterr().err
    assert status == MassFileError.status and "request 1: status 1" in err
    assert "leave the measurement range" in err
    assert second == first  # byte-identical recordings, whatever the host did
