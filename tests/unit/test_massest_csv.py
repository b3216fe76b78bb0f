"""Issue 23: real recordings as plain CSV with named columns and units (linear and rotary
axes, a torque or a current channel), and the one-file report (figure + JSON)."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from softplc.cli import main
from softplc.errors import MassFileError, SingularFitError
from softplc.machines.machining import synth, tuning
from softplc.machines.machining.csvrec import format_csv, parse_csv
from softplc.machines.machining.estimator import estimate
from softplc.machines.machining.params import default_template
from softplc.machines.machining.settings import format_settings, thesis_settings

DEG = math.pi / 180
UNITS_LINEAR = ("ms", "mm", "mm/min", "m/s^2", "Nm")
SI_LINEAR = (1e3, 1e3, 6e4, 1.0)


def columns(sc: synth.Scenario, run: synth.Run) -> tuple[np.ndarray, ...]:
    """t (s), x, v, a (SI) and the motor torque (Nm) of a noise-free synthetic run."""
    _, _, _, total = synth.kinematics(run, np.zeros(1))
    t = np.arange(1, int(total / 0.003) + 1) * 0.003
    x, v, a, _ = synth.kinematics(run, t)
    return t, x, v, a, synth.force(sc, x, v, a) / sc.ratio


def csv_text(sc: synth.Scenario, run: synth.Run, units: tuple[str, ...],
             scale: tuple[float, ...], last: float = 1.0) -> str:
    t, x, v, a, torque = columns(sc, run)
    return format_csv(t * scale[0], x * scale[1], v * scale[2], a * scale[3], torque * last,
                      units)  # type: ignore[arg-type]


def test_linear_csv_gives_the_mass_of_the_dta_path(tmp_path):
    sc = synth.Scenario().without_noise()
    cal, meas = (parse_csv(csv_text(sc, r, UNITS_LINEAR, SI_LINEAR), f"{n}.csv")
                 for n, r in (("cal", sc.calibration), ("meas", sc.measurement)))
    s = thesis_settings()
    e = estimate(meas, cal, s)
    assert e.mass == pytest.approx(22699.0, rel=5e-4)  # N14
    dta = estimate(*reversed(synth.recordings(sc)), s)  # the scope files of the same runs
    assert e.mass == pytest.approx(dta.mass, rel=1e-4)
    assert not e.measurement.rotary


def rotary_case() -> tuple[synth.Scenario, object]:
    """A rotary table: J = 12 kg·m² behind a 50:1 gear, settings in degrees."""
    sc = synth.Scenario(mass=12.0, ratio=50.0, coulomb=2.0, viscous=1.5, pos_force=(0.5, 0.3),
                        noise=(0.0,) * 4,
                        measurement=synth.Run(-200 * DEG, 100 * DEG, 60 * DEG, 120 * DEG),
                        calibration=synth.Run(-240 * DEG, 140 * DEG, 20 * DEG, 200 * DEG))
    s = replace(thesis_settings(), pos_conv=DEG, vel_conv=DEG, acc_conv=DEG, start_cal=-240.0,
                end_cal=140.0, start_m=-200.0, end_m=100.0, a_lim=120.0,
                ratio=50.0).validate()
    return sc, s


def test_rotary_axis_in_degrees_and_rpm_with_a_current_channel(tmp_path, capsys):
    sc, s = rotary_case()
    units = ("s", "deg", "1/min", "deg/s^2", "A")
    scale = (1.0, 1 / DEG, 60 / (2 * math.pi), 1 / DEG)
    km = thesis_settings().km_sys
    for name, run in (("IMCal_.csv", sc.calibration), ("IMMea_.csv", sc.measurement)):
        # the drive's current, + M / Km (the opposite of the thesis's sign): same estimate
        (tmp_path / name).write_text(csv_text(sc, run, units, scale, 1 / km), encoding="utf-8")
    (tmp_path / "settings.txt").write_text(format_settings(s), encoding="utf-8")
    (tmp_path / "MPSetTemp.H").write_bytes(default_template())
    res = tuning.tune_files(tmp_path / "settings.txt", tmp_path / "IMCal_.csv",
                            tmp_path / "IMMea_.csv", tmp_path / "MPSetTemp.H", None)
    assert res.estimate.measurement.rotary
    assert res.estimate.mass == pytest.approx(12.0, rel=5e-4)  # kg·m² at the table
    assert "kg·m²" in res.summary() and "rad/s²" in res.summary() and "A/rad" in res.summary()
    # the position-dependent torque needs the calibration here too
    nocal = tuning.tune_files(tmp_path / "settings.txt", None, tmp_path / "IMMea_.csv",
                              tmp_path / "MPSetTemp.H", None)
    assert abs(nocal.estimate.mass / 12.0 - 1) > 10 * abs(res.estimate.mass / 12.0 - 1)


@pytest.mark.parametrize(("text", "message"), [
    ("time [s],position [mm],velocity [mm/min],acceleration [m/s^2]\n1,2,3,4\n",
     "no torque or current column"),
    ("time [s],position [furlong],velocity [mm/min],acceleration [m/s^2],torque [Nm]\n",
     "unit 'furlong' for position"),
    ("time [s],position [deg],velocity [mm/min],acceleration [m/s^2],torque [Nm]\n1,2,3,4,5\n"
     "2,2,3,4,5\n", "mix linear and rotary"),
    ("time [s],position [mm],velocity [mm/s],acceleration [m/s^2],torque [Nm]\n1,2,3,4,5\n"
     "1,2,3,4,5\n", "increase strictly"),
    ("time [s],position [mm],velocity [mm/s],acceleration [m/s^2],torque [Nm]\n1,2,3,4,x\n",
     ":2: '1,2,3,4,x': expected 5 numbers"),
    ("t [s];t [ms];x [mm];v [mm/s];a [m/s^2];i [A]\n", "two time columns"),
    ("# only a comment\n", "no header"),
])
def test_csv_refusals(text, message):
    with pytest.raises(MassFileError, match=message):
        parse_csv(text, "r.csv")


def test_flat_csv_column_is_refused():
    rec = parse_csv("time [s];x [mm];v [mm/s];a [m/s^2];torque [Nm]\n1;1;1;1;1\n2;2;2;2;1\n")
    with pytest.raises(SingularFitError, match="current column is flat"):
        rec.to_trace(thesis_settings())


def test_report_figure_and_json(tmp_path, capsys):
    tuning.write_example(tmp_path, table="machine")
    out = tmp_path / "report.svg"
    assert main(["tune", "--dir", str(tmp_path), "--report", str(out), "--dry-run"]) == 0
    data = json.loads(out.with_suffix(".json").read_text(encoding="utf-8"))
    assert out.read_text(encoding="utf-8").startswith("<?xml")
    assert data["row"] == {"number": 4, "inert": 22500.0} and data["unit"] == "kg"
    assert data["mass"] == pytest.approx(22699.0, rel=0.01)
    changed = {p["name"]: (p["template"], p["new"]) for p in data["parameters"] if p["changed"]}
    assert changed == {"MP2500": (3350.0, 5360.0), "MP2510": (43.5, 69.6)}
    assert len(data["parameters"]) == 23 and len(data["residuals"]) == 4
    # noise sd 0.5 Nm = 0.296 A of current: the residuals are that noise, no model error
    for r in data["residuals"]:
        assert 0.27 < r["current_rms_A"] < 0.33 and r["samples"] > 100
    assert not (tmp_path / "MPSet.H").exists()  # --dry-run writes no macro
    assert "report written" in capsys.readouterr().err


def test_cli_reads_csv_recordings(tmp_path, capsys):
    sc = synth.Scenario().without_noise()
    tuning.write_example(tmp_path)
    for name, run in (("cal.csv", sc.calibration), ("meas.csv", sc.measurement)):
        (tmp_path / name).write_text(csv_text(sc, run, UNITS_LINEAR, SI_LINEAR), "utf-8")
    assert main(["tune", "--dir", str(tmp_path), "--calibration", str(tmp_path / "cal.csv"),
                 "--measurement", str(tmp_path / "meas.csv"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["row"] == 2
    (tmp_path / "bad.csv").write_text("time [s],x [yd]\n", "utf-8")
    assert main(["tune", "--dir", str(tmp_path), "--measurement",
                 str(tmp_path / "bad.csv")]) == 1
    assert "unit 'yd'" in capsys.readouterr().err


def test_write_example_refuses_an_unknown_table(tmp_path):
    from softplc.errors import ConfigError

    with pytest.raises(ConfigError, match="table"):
        tuning.write_example(Path(tmp_path), table="other")
