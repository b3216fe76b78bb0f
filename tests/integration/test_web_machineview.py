"""The Machine tab's data (softplc/web/machineview.py through LiveViews.devices_now) for the
servo table, the cutting table and the machining centre, in process: each device family's
geometry, the FE envelope over the servo-rate trace, the Grafcet's active steps and the
mass estimator's words."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from softplc.access import AccessPort
from softplc.plc import PLC
from softplc.web.control import Controller
from softplc.web.live import LiveViews, dumps

PROGRAMS = Path(__file__).resolve().parents[2] / "ladder_programs"


def machine(name: str) -> tuple[PLC, LiveViews]:
    cfg = tomllib.loads((PROGRAMS / f"{name}.toml").read_text(encoding="utf-8"))
    plc = PLC.from_file(PROGRAMS / f"{name}.il", cfg)
    plc.scan()
    return plc, LiveViews(Controller(AccessPort(plc)))


@pytest.fixture
def servo_table():
    plc, views = machine("servo_table")
    yield plc, views
    plc.close()


def test_servo_axis_view_geometry_and_position(servo_table):
    plc, views = servo_table
    snap = views.devices_now()
    x = snap["devices"]["X"]["view"]
    assert x["counts_per_mm"] == 409.6
    assert (x["lo"], x["hi"]) == (-217088.0, 4096.0)  # the limit switches (geometry)
    assert x["x"] == plc.devices["X"].position == -8000.0 and not x["enabled"]
    assert "steps" not in snap and "estimate" not in snap  # no Grafcet, no scope
    dumps(views.machine_view(snap, 0))  # JSON as the page gets it


def test_fe_envelope_covers_the_servo_trace_since_the_last_update(servo_table):
    plc, views = servo_table
    plc["%I0.1"] = 1  # start, then home: the axes move under closed loops
    plc.scan(2)
    plc["%I0.1"] = 0
    plc["%MW100"] = 2
    plc.run(0.3)
    views.devices_now()  # the previous update: the envelope starts here
    t0 = plc.time
    plc.run(0.1)
    x = views.devices_now()["devices"]["X"]["view"]
    dev = plc.devices["X"]
    fes = [e for t, _cp, _ap, e, _u in dev.samples() if t >= t0 - 1e-9]
    assert len(fes) > 100 and max(fes) - min(fes) > 0.5  # a moving axis's FE varies
    assert x["fe_lo"] == pytest.approx(min(fes)) and x["fe_hi"] == pytest.approx(max(fes))
    assert x["fe_lo"] <= x["fe"] <= x["fe_hi"] and x["enabled"]
    assert x["cmd"] == pytest.approx(x["x"] + x["fe"])


def test_cutting_table_trace_and_grafcet_steps():
    plc, views = machine("cutting_table")
    try:
        plc.run(0.5)  # homing: step 1 HOME_SEARCH
        snap = views.devices_now()
        assert snap["devices"]["trace"]["view"]["axes"] == ["X", "Y"]
        assert snap["devices"]["trace"]["view"]["pen"] == "torch"
        assert snap["devices"]["X"]["view"]["counts_per_mm"] == 100000.0
        assert snap["steps"]["active"] == [n for n in range(96) if plc[f"%X{n}"]] == [1]
        assert snap["steps"]["titles"]["1"].startswith("HOME_SEARCH")
        view = views.machine_view(snap, 0)
        assert view["trace_total"] == len(plc.trace) > 100 and len(view["trace"][0]) == 5
    finally:
        plc.close()


def test_machining_centre_step_and_estimate_words():
    plc, views = machine("mass_tuning")
    try:
        snap = views.devices_now()
        assert snap["steps"]["active"] == [0]
        assert snap["estimate"]["answers"] == 0
        plc["%MF406"], plc["%MF408"], plc["%MW404"], plc["%MW402"] = 22650.5, 310.0, 3, 1
        plc["%M205"] = plc["%M200"] = 1  # automatic mode and the softkey: the sequence starts
        plc.run(0.5)
        snap = views.devices_now()
        e = snap["estimate"]
        assert (e["mass_kg"], e["uncertainty_kg"], e["row"], e["answers"]) == \
            (22650.5, 310.0, 3, 1)
        assert snap["steps"]["active"] and snap["steps"]["active"] != [0]
        x = snap["devices"]["X"]["view"]
        assert x["x"] < 0 and x["v"] < 0  # on its way to Q26 (-480 mm)
        assert x["load_mass_ratio"] == pytest.approx(0.5132667)
    finally:
        plc.close()


def test_cutting_table_work_frame_is_the_hosts():
    """The trace's work frame ([devices.trace.work]): before homing the origin is unknown
    (homed False); once the program has homed (%M110), the origin in the trace's frame puts
    the tool where the PLC reports it (%MD112 / %MD114, µm: what `softplc cut` prints)."""
    cfg = tomllib.loads((PROGRAMS / "cutting_table.toml").read_text(encoding="utf-8"))
    cfg["devices"]["X"]["start"] = cfg["devices"]["Y"]["start"] = 100000.0  # 1 mm
    plc = PLC.from_file(PROGRAMS / "cutting_table.il", cfg)
    views = LiveViews(Controller(AccessPort(plc)))
    try:
        plc.scan()
        work = views.devices_now()["devices"]["trace"]["view"]["work"]
        assert work["homed"] is False and work["homed_by"] == "%M110"
        assert work["area"] == [240.0, 240.0]
        assert plc.run_until(lambda p: p["%M110"], timeout=20)
        plc.run(0.2)
        snap = views.devices_now()
        work = snap["devices"]["trace"]["view"]["work"]
        assert work["homed"] is True
        for axis, pos_um in (("X", "%MD112"), ("Y", "%MD114")):
            v = snap["devices"][axis]["view"]
            work_mm = (v["x"] - work["origin"]["XY".index(axis)]) / v["counts_per_mm"]
            assert work_mm == pytest.approx(plc[pos_um] / 1000, abs=0.001)
            assert v["x"] / v["counts_per_mm"] > work_mm + 25  # machine: the 30 mm retract
        assert snap["devices"]["X"]["drive_homed"] is False  # the PLC homed, not the drive
    finally:
        plc.close()


def test_thin_keeps_what_a_drawing_at_the_cell_shows():
    """thin: a slow move (many samples per cell) becomes about one sample per cell; every
    pen change keeps the samples on both sides; the first and the last are kept."""
    from softplc.web.live import thin

    rows = [(i * 0.001, i * 0.1, 0.0, 1 if i < 500 else 0, 0) for i in range(1000)]
    rows += [(1.0 + i * 0.001, 100.0, i * 0.1, 1, 0) for i in range(1000)]
    kept = thin(rows, [5.0, 5.0])
    assert kept[0] == rows[0] and kept[-1] == rows[-1]
    assert 40 < len(kept) < 70  # 100 mm / 5 twice, and the pen changes
    for i in (499, 500, 999, 1000):  # the pen lifts at 500, goes down at 1000
        assert rows[i] in kept
    assert thin(rows[:2], [5.0, 5.0]) == rows[:2] and thin(rows, [0.0, 0.0]) == rows
