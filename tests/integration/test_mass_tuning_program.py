"""ladder_programs/mass_tuning.il through the PLC API, on the virtual clock: the softkey's
enable logic, one press = one run, the reduced acceleration limit and its restoration on
every exit, the host handshake (answer, refusal, timeout), applying at standstill, faults,
reset, lamps. A short geometry (4-6 mm moves, 10 ms dwells) keeps each run under 2 s of
machine time; the host is emulated by writing its words (the daemon test uses the real
one)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import pytest

from softplc.plc import PLC

ROOT = Path(__file__).resolve().parents[2]
IL = ROOT / "ladder_programs" / "mass_tuning.il"
TOML = ROOT / "ladder_programs" / "mass_tuning.toml"
IDLE, REQUEST_WAIT, APPLY, FAULT = 0, 29, 30, 40
MEASURING = range(16, 26)  # steps run with the reduced acceleration limit


def fast_config(directory: Path, **timers: Any) -> dict[str, Any]:
    cfg = tomllib.loads(TOML.read_text(encoding="utf-8"))
    cfg["devices"]["scope"]["directory"] = str(directory)
    cfg["constants"].update({"%KD0": -3000, "%KD2": 3000, "%KD4": -2000, "%KD6": 2000,
                             "%KD8": 0, "%KW10": 600, "%KW11": 1200, "%KW12": 1200})
    for name in list(cfg["timers"]):
        if name != "%TM10":
            cfg["timers"][name] = {"base": "10ms", "preset": 1}
    cfg["timers"].update(timers)
    return cfg


def plc_for(directory: Path, **timers: Any) -> PLC:
    p = PLC.from_file(IL, fast_config(directory, **timers))
    p.scan(3)
    p["%M205"] = 1  # automatic mode from the HMI
    p.scan(2)
    return p


def press(p: PLC) -> None:
    p["%M200"] = 1
    p.scan(2)


def answer(p: PLC, status: int = 0, row: int = 2, mps: float = 3650.0) -> None:
    """The host: result words and EST_ACK := EST_REQ (as handshake.serve writes them)."""
    if status == 0:
        p["%MW404"] = row
        for i in range(22):
            p[f"%MF{420 + 2 * i}"] = mps + i
    p["%MW403"] = status
    p["%MW402"] = p["%MW401"]


def run_to(p: PLC, step: int, timeout: float = 30.0) -> dict[int, float]:
    """Scan until the step is reached; returns ACC_LIMIT seen per step on the way."""
    seen: dict[int, float] = {}

    def cond(q: PLC) -> bool:
        seen.setdefault(q["%MW400"], q["%MF300"])
        return q["%MW400"] == step

    assert p.run_until(cond, timeout), f"stuck in step {p['%MW400']}"
    return seen


def test_softkey_enable_logic(tmp_path):
    p = PLC.from_file(IL, fast_config(tmp_path))
    p.scan(3)
    press(p)  # not in automatic mode: ignored
    assert p["%MW400"] == IDLE and not p["%Q0.0"] and not p["%M201"]
    p["%I0.1"] = 1  # the mode switch
    p.scan(2)
    assert p["%M201"] and p["%Q0.0"]
    p["%I0.0"] = 1  # the push button
    p.scan(2)
    assert p["%MW400"] >= 1 and p["%Q0.2"] and not p["%Q0.0"]
    p["%I0.0"] = 0
    assert p["%M200"] == 0  # the HMI bit is reset by the PLC


def test_full_sequence_applies_the_row_at_standstill(tmp_path):
    p = plc_for(tmp_path)
    kp0 = p.devices["X"].gains.kp
    assert p["%MF300"] == 1.0  # ACC_LIMIT at power-up (%KF16)
    press(p)
    press(p)  # a second press while running is ignored
    seen = run_to(p, REQUEST_WAIT)
    assert all(seen[s] == pytest.approx(0.22) for s in MEASURING if s in seen)
    assert seen[13] == 1.0 and p["%MF300"] == 1.0  # restored before the request
    assert p["%MW401"] == 1  # one request
    assert (tmp_path / "IMCal_.dta").exists() and (tmp_path / "IMMea_.dta").exists()
    assert p["%MW207"] == 1 and p["%MW204"] == round(1200 / 60 / 1.0)  # trapezoid, ms
    answer(p, row=2)
    run_to(p, IDLE, 2.0)
    assert p["%MW496"] == 2 and p["%MW498"] == 1
    assert [p[f"%MF{500 + 2 * i}"] for i in range(22)] == [3650.0 + i for i in range(22)]
    assert p["%MW218"] & 4  # applied while in position
    # the drive retuned the axis from MP2500 (the template's 3350 = the configured gains)
    assert p["%MW499"] == 1 and p["%MW497"] == 0
    assert p.devices["X"].gains.kp == pytest.approx(kp0 * 3650 / 3350)
    # a second run, the host now answers row 1
    press(p)
    run_to(p, REQUEST_WAIT)
    assert p["%MW401"] == 2
    answer(p, row=1, mps=3550.0)
    run_to(p, IDLE, 2.0)
    assert p["%MW496"] == 1 and p["%MF500"] == 3550.0 and p["%MW498"] == 2
    assert p["%MW499"] == 2 and p.devices["X"].gains.kp == pytest.approx(kp0 * 3550 / 3350)


def test_host_refusal_and_timeout_leave_the_parameters(tmp_path):
    p = plc_for(tmp_path, **{"%TM10": {"base": "100ms", "preset": 5}})
    press(p)
    run_to(p, REQUEST_WAIT)
    answer(p, status=5)  # u/m > Acc_uncert: the MP words are not written
    run_to(p, FAULT, 1.0)
    assert p["%MW470"] == 3 and p["%MW498"] == 0 and p["%MF500"] == 0.0
    assert p["%MW499"] == 0  # the drive's gains untouched
    assert p["%MF300"] == 1.0
    blink = set()
    for _ in range(30):
        p.run(0.1)
        blink.add(p["%Q0.1"])
    assert blink == {0, 1}  # the red lamp blinks
    press(p)  # ignored in FAULT
    assert p["%MW400"] == FAULT
    p["%M203"] = 1  # reset from the HMI
    p.scan(2)
    assert p["%MW400"] == IDLE and p["%M203"] == 0 and not p["%Q0.1"]
    press(p)
    run_to(p, REQUEST_WAIT)
    p.run(0.6)  # no answer: the timeout (0.5 s here)
    assert p["%MW400"] == FAULT and p["%MW470"] == 4 and p["%MW498"] == 0
    answer(p)  # a late answer changes nothing
    p.scan(5)
    assert p["%MW400"] == FAULT and p["%MW498"] == 0


def test_axis_fault_during_the_measurement_restores_the_acceleration_limit(tmp_path):
    p = plc_for(tmp_path)
    press(p)
    run_to(p, 19)  # the measurement move, ACC_LIMIT reduced
    assert p["%MF300"] == pytest.approx(0.22)
    p.devices["X"].set_fault("amp_fault")
    run_to(p, FAULT, 1.0)
    p.scan(2)
    assert p["%MW470"] == 1 and p["%MF300"] == 1.0 and not p["%M241"]
    p.devices["X"].set_fault("none")
    p["%I0.2"] = 1  # the reset push button: back to idle, the axis error cleared
    p.scan(3)
    p["%I0.2"] = 0
    p.scan(3)
    assert p["%MW400"] == IDLE and not p["%MW218"] & (1 << 11) and p["%M201"]


def test_leaving_automatic_mode_is_a_fault(tmp_path):
    p = plc_for(tmp_path)
    press(p)
    run_to(p, 17)
    p["%M205"] = 0
    p.scan(3)
    assert p["%MW400"] == FAULT and p["%MW470"] == 5 and p["%MF300"] == 1.0


def test_two_runs_write_identical_files(tmp_path):
    files = []
    for name in ("a", "b"):
        d = tmp_path / name
        p = plc_for(d)
        press(p)
        run_to(p, REQUEST_WAIT)
        files.append([(d / f).read_bytes() for f in ("IMCal_.dta", "IMMea_.dta")])
    assert files[0] == files[1]


def test_the_program_runs_the_ideal_feed_axis_too(tmp_path):
    """`type = "feed_axis"` in place of the servo axis, nothing else changed: the same
    sequence, no following error, the row applied to it."""
    cfg = fast_config(tmp_path)
    cfg["devices"]["X"]["type"] = "feed_axis"
    p = PLC.from_file(IL, cfg)
    p.scan(3)
    p["%M205"] = 1
    p.scan(2)
    press(p)
    run_to(p, REQUEST_WAIT)
    assert p["%MW470"] == 0 and p["%MF216"] == 0.0  # FE_MAX of the last move: none
    answer(p, row=2)
    run_to(p, IDLE, 2.0)
    assert p["%MW498"] == 1 and p["%MW499"] == 1 and p.devices["X"].type_name == "feed_axis"
    assert (tmp_path / "IMMea_.dta").exists()
