"""Snapshots owned by their objects: Engine.snapshot/restore, Device.state/set_state, timers
saving their elapsed time."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc import PLC

ROOT = Path(__file__).resolve().parents[2] / "ladder_programs"


def drawing_plc() -> PLC:
    plc = PLC.from_file(ROOT / "drawing_table.il", config=ROOT / "drawing_table.toml")
    for dev in plc.devices.values():  # no trace file from a test
        if hasattr(dev, "csv_path"):
            dev.csv_path = None
    return plc


def observable(plc: PLC) -> tuple:
    """What the scans computed (the measured scan times %SW30-%SW32 are wall-clock)."""
    for k in (30, 31, 32):
        plc.mem.sw.w[k] = 0
    mem = plc.mem.snapshot()
    return (mem, plc.time, plc.scan_count, plc.state,
            {n: d.state() for n, d in plc.devices.items()},
            plc.program_state.snapshot())


def start_segment(plc: PLC) -> None:
    plc["%MW0"], plc["%MW1"], plc["%MW5"] = 1000, 500, 1
    plc["%MW3"] = 120


def test_engine_restore_replays_exactly():
    plc = drawing_plc()
    plc.run(seconds=2)  # homing
    start_segment(plc)
    plc.run(seconds=0.3)
    snap = plc.engine.snapshot()
    plc.run(seconds=0.5)
    after = observable(plc)
    plc.engine.restore(snap)
    plc.run(seconds=0.5)
    assert observable(plc) == after  # the snapshot held everything the scans depend on


@pytest.mark.parametrize("seconds", [0.05, 0.4])
def test_every_device_attribute_a_scan_changes_is_in_its_state(seconds):
    """Device.state() declares the simulated state: whatever update() changes comes back
    with set_state (records, append-only lists, are cut back to their length)."""
    plc = drawing_plc()
    plc.run(seconds=2)
    start_segment(plc)
    plc.run(seconds=seconds)
    before = {n: dict(vars(d)) for n, d in plc.devices.items()}
    lengths = {n: {k: len(v) for k, v in vars(d).items() if isinstance(v, list)}
               for n, d in plc.devices.items()}
    states = {n: d.state() for n, d in plc.devices.items()}
    plc.run(seconds=0.3)
    for name, dev in plc.devices.items():
        dev.set_state(states[name])
        for k, v in vars(dev).items():
            if isinstance(v, list):
                assert len(v) == lengths[name][k], (name, k)
            elif isinstance(v, bool | int | float | str | tuple) or v is None:
                assert v == before[name][k], f"{name}.{k} is not in {type(dev).__name__}.STATE"


def test_timer_state_is_elapsed_time_whatever_the_clock():
    cfg = {"timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 100}}}
    src = "BLK %TM0\nLD %M0\nIN\nOUT_BLK\nLD Q\nST %Q0.0\nEND_BLK\n"
    a = PLC.from_source(src, cfg)
    a.run(seconds=5)  # the clock is well past 0
    a["%M0"] = 1
    a.run(seconds=0.4)
    st = a.mem.blocks["TM"][0].state()
    assert "_t0" not in st and 390_000 <= st["_elapsed_us"] <= 410_000
    b = PLC.from_source(src, cfg)  # a new run: its clock starts at 0
    b["%M0"] = 1
    b.scan()
    b.mem.blocks["TM"][0].set_state(st)
    b.run(seconds=0.55)
    assert not b["%Q0.0"]
    b.run(seconds=0.1)
    assert b["%Q0.0"] and b["%TM0.V"] == 100  # 0.4 s + 0.6 s = the 1 s preset


def test_debugger_back_uses_engine_snapshots():
    from softplc.debug.session import Session

    plc = PLC.from_file(ROOT / "star_delta.il", config=ROOT / "star_delta.toml")
    ses = Session(plc)
    plc["%I0.0"] = 1
    ses.execute("scan 5")
    t5, mem5 = plc.time, plc.mem.snapshot()
    ses.execute("scan 5")
    assert plc.time > t5
    ses.execute("back 5")
    assert plc.time == pytest.approx(t5) and plc.mem.snapshot() == mem5
