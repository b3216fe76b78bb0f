"""End to end on loopback: `softplc run` with mass_tuning.il (`--speed max`), the softkey
pressed over Modbus, `softplc tune` in online mode estimating from the recorder's files, the
PLC applying row 2 for 22699 kg, then row 1 after the load drops to 18000 kg.

The NC macro's geometry (mass-estimation.md §1: 100 mm triangles at 0.4 m/s², calibration
-30..130 mm at 2000 mm/min) instead of the settings file's: the same sequence in about
27 s of machine time instead of 59 s (the spec's second configuration), to keep the suite
short."""

from __future__ import annotations

import re
import threading
from pathlib import Path

import pytest
from daemon_util import Daemon

from softplc.cli import main
from softplc.machines.machining import handshake, tuning
from softplc.machines.machining.mpfile import MPFile
from softplc.modbus.host import ModbusHost

ROOT = Path(__file__).resolve().parents[2]
IL = ROOT / "ladder_programs" / "mass_tuning.il"
TOML = ROOT / "ladder_programs" / "mass_tuning.toml"
MACRO = {"%KD0": -30000, "%KD2": 130000, "%KD4": 0, "%KD6": 100000, "%KD8": 0,
         "%KF14": 0.4}
SOFTKEY, AUTO, LOAD_WORD, ACTIVE_MPS, STATE = 200, 205, 290, 500, 400
RETUNED = 497  # the drive: %MW497 error, %MW499 sets applied to the axis
M0, CONFIGURED = 15000.0, 0.5132667  # mass_tuning.toml: table mass, workpiece ratio


def macro_toml(path: Path) -> Path:
    text = TOML.read_text(encoding="utf-8")
    for key, value in MACRO.items():
        text, n = re.subn(rf'^"{key}" = \S+', f'"{key}" = {value}', text, flags=re.M)
        assert n == 1, key
    path.write_text(text, encoding="utf-8")
    return path


def run_once(port: int, directory: Path) -> list[int]:
    """Press the softkey and answer the request with `softplc tune`; returns its exit code.
    About 8 s wall on a quiet machine; the long --wait covers a heavily loaded one, where
    the daemon at --speed max can fall below real time."""
    rc: list[int] = []
    t = threading.Thread(target=lambda: rc.append(main(
        ["tune", "--dir", str(directory), "--port", str(port), "--once", "--wait", "150",
         "--poll", "0.02"])))
    t.start()
    with ModbusHost("127.0.0.1", port) as h:
        h._call("softkey", lambda c, **kw: c.write_coil(SOFTKEY, True, **kw))
        t.join(170)
        if rc != [0]:  # say where the PLC is
            rc.append(h.read_words(STATE, 1)[0])
            rc.append(h.read_words(470, 1)[0])
    return rc


def wait_idle(h: ModbusHost, applied: int) -> None:
    for _ in range(500):
        if h.read_words(498, 1)[0] == applied and h.read_words(STATE, 1)[0] == 0:
            return
        threading.Event().wait(0.02)
    raise AssertionError(f"not applied: step {h.read_words(STATE, 1)[0]}")


@pytest.mark.timeout(400)
def test_softkey_estimate_apply_row_2_then_row_1(tmp_path, capsys):
    tuning.write_example(tmp_path, geometry="macro")  # settings + template
    for f in (tuning.CAL_FILE, tuning.MEAS_FILE):
        (tmp_path / f).unlink()  # the recorder writes them
    cfg = macro_toml(tmp_path / "machine.toml")
    daemon = Daemon(tmp_path, "--config", str(cfg), "--speed", "max", program=IL)
    try:
        with ModbusHost("127.0.0.1", daemon.port) as h:
            h._call("auto", lambda c, **kw: c.write_coil(AUTO, True, **kw))
        assert run_once(daemon.port, tmp_path) == [0]
        with ModbusHost("127.0.0.1", daemon.port) as h:
            wait_idle(h, 1)
            mass = h.read_float(handshake.F_MASS)
            assert mass == pytest.approx(22699.0, rel=0.01)
            assert h.read_words(handshake.W_ROW, 1) == [2] and h.read_words(496, 1) == [2]
            assert h.read_float(ACTIVE_MPS) == 3650.0  # MP2500 of row 2
            # the drive retuned the axis: no error, applied by the PLC once, by the drive once
            assert h.read_words(RETUNED, 3) == [0, 1, 1]
            assert h.read_float(300) == 1.0  # ACC_LIMIT restored
        first = (tmp_path / tuning.MEAS_FILE).read_bytes()
        assert MPFile.read(tmp_path / tuning.OUTPUT_FILE).values()[1] == 3650.0
        # the workpiece is lighter: 18000 kg
        with ModbusHost("127.0.0.1", daemon.port) as h:
            h.write_float(LOAD_WORD, 18000.0 / M0 - 1 - CONFIGURED)
        assert run_once(daemon.port, tmp_path) == [0]
        with ModbusHost("127.0.0.1", daemon.port) as h:
            wait_idle(h, 2)
            assert h.read_float(handshake.F_MASS) == pytest.approx(18000.0, rel=0.01)
            assert h.read_words(496, 1) == [1] and h.read_float(ACTIVE_MPS) == 3550.0
            assert h.read_words(RETUNED, 3) == [0, 2, 2]
        assert (tmp_path / tuning.MEAS_FILE).read_bytes() != first
        err = capsys.readouterr().err
        assert "request 1: status 0" in err and "request 2: status 0" in err
    finally:
        daemon.stop()
