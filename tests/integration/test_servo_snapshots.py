"""The servo axis's snapshots (Device.state/set_state, Engine.snapshot/restore) and its exact
fast path at a fixed point of the servo loop (issue 12's benchmark work)."""

from __future__ import annotations

import tomllib

import pytest
from daemon_util import ROOT

from softplc import PLC
from softplc.devices.axis import Ctl
from softplc.devices.axis.rig import Rig
from softplc.devices.axis.runner import LoopRunner

TOML = ROOT / "ladder_programs" / "servo_table.toml"
IL = ROOT / "ladder_programs" / "servo_table.il"


def moving_rig(**overrides) -> Rig:
    rig = Rig.from_toml(TOML, "X", "Y", require_home=False, start=-80000.0, **overrides)
    for a in "XY":
        rig.command(a, Ctl.ENABLE)
    rig.run(0.2)
    for a in "XY":
        rig.pulse(a, Ctl.EXECUTE, target=round(rig.axes[a].actual) + 14336, speed=69632,
                  acc_ms=125, scurve_ms=40)
    return rig


def observed(rig: Rig) -> tuple:
    return (bytes(rig.mem.mw.buf), {n: (ax.state(), list(ax.trace), ax.samples()[-3:])
                                    for n, ax in rig.axes.items()})


def test_axis_state_round_trip_replays_exactly():
    rig = moving_rig()
    rig.run(0.1)  # mid-move: a trajectory, following errors, the integrator
    states = {n: ax.state() for n, ax in rig.axes.items()}
    words, t_us = bytes(rig.mem.mw.buf), rig.t_us
    rig.run(0.3)
    after = observed(rig)
    assert all(ax.state() != states[n] for n, ax in rig.axes.items())
    for n, ax in rig.axes.items():
        ax.set_state(states[n])
        assert len(ax.trace) == states[n]["trace"]  # the record is cut back
    rig.mem.mw.buf[:] = words
    rig.t_us = t_us
    rig.run(0.3)
    assert observed(rig) == after


def test_axis_state_restores_the_moving_mass():
    rig = moving_rig()
    ax = rig.axes["X"]
    st = ax.state()
    k0 = ax.K
    ax.set_load_mass_ratio(2.0)
    assert ax.K != k0
    ax.set_state(st)
    assert ax.K == k0 and ax.load_mass_ratio == st["load_mass_ratio"]


def test_engine_snapshot_covers_the_servo_axes():
    """Engine.snapshot/restore (the debugger's `back`) with servo_table.il and both axes."""
    conf = tomllib.loads(TOML.read_text())
    for a in ("X", "Y"):
        conf["devices"][a]["start"] = -2500.0
    plc = PLC.from_file(IL, conf)
    plc["%MW100"] = 5  # remote start: home X then Y
    plc.run(0.6)  # homing in progress
    snap = plc.engine.snapshot()
    plc.run(0.4)
    after = observable(plc)
    plc.engine.restore(snap)
    plc.run(0.4)
    assert observable(plc) == after
    assert after[1]["X"]["k"] > 2000 and after[1]["X"]["homing"]  # the axis was moving
    plc.close()


def observable(plc: PLC) -> tuple:
    for k in (30, 31, 32):  # the measured scan times are wall clock
        plc.mem.sw.w[k] = 0
    return plc.mem.snapshot(), {n: d.state() for n, d in plc.devices.items()}


def simulated(rig: Rig) -> tuple:
    """`observed` without the fast path's own bookkeeping (`_fixed`, `_creep`)."""
    words, axes = observed(rig)
    for st, _, _ in axes.values():
        del st["_fixed"], st["_creep"]
    return words, axes


@pytest.mark.parametrize("overrides", [{}, {"ivars.Ixx33": 0}], ids=["ki", "no-ki"])
def test_fixed_point_fast_path_is_exact(monkeypatch, overrides):
    """The same run with the fast path off gives the same trace, words and state bit for
    bit, and the fast path was taken (at rest before the move; after it, a fixed point
    without an integrator, a creep with one: stuck by the friction a few counts off, the
    integrator winding inside one DAC step)."""
    def run() -> tuple:
        rig = moving_rig(**overrides)
        rig.run(1.5)
        return simulated(rig)

    used, creeps = [], []
    repeat = LoopRunner._repeat

    def counting(self, n):
        (creeps if self.a._creep else used).append(n)
        return repeat(self, n)

    monkeypatch.setattr(LoopRunner, "_repeat", counting)
    fast = run()
    assert sum(used) > 400  # cycles skipped
    if overrides == {}:
        assert sum(creeps) > 1000  # (the integrator's creeps after the move)
    monkeypatch.setattr(LoopRunner, "_fixed_candidate", lambda self: False)
    slow = run()
    assert fast == slow
