"""PMACTuningPro's tuning moves on a simulated axis gathered at the servo rate
(softplc/machines/servo/tuning.py, `softplc servo --sim`, `compare`, `disturb`)."""

from __future__ import annotations

import pytest
from daemon_util import ROOT

from softplc.devices.axis.ivars import IVarError
from softplc.machines.servo import tuning as st

CFG = ROOT / "ladder_programs" / "servo_table.toml"


def test_step_metrics_match_the_gathered_response():
    c = st.run_move("step", "X", 1000, config=CFG)
    m = st.metrics(c)
    dt = c.t[1] - c.t[0]
    assert dt == pytest.approx(4 / 9034.6 * 1000)  # one row per servo tick, ms
    assert c.cp[0] == 1000 and c.fe[0] == 1000 == m["max_fe"]  # the step at the first tick
    peak = max(c.ap)
    assert m["overshoot_pct"] == pytest.approx((peak - 1000) / 10)
    t10 = next(t for t, a in zip(c.t, c.ap, strict=True) if a >= 100)
    t90 = next(t for t, a in zip(c.t, c.ap, strict=True) if a >= 900)
    assert m["rise_ms"] == pytest.approx(t90 - t10)
    assert 5 < m["rise_ms"] < 40 and m["overshoot_pct"] > 0
    inside = [abs(f) <= c.band for t, f in zip(c.t, c.fe, strict=True)
              if t >= c.t[0] + m["settling_ms"] - 1e-9]
    assert all(inside) and abs(c.fe[-1]) <= c.band


def test_step_return_dwells_then_returns():
    c = st.run_move("step-return", "X", 1000, config=CFG, dwell_ms=200)
    back = next(t for t, cp in zip(c.t, c.cp, strict=True) if cp == 0)
    assert back == pytest.approx(200, abs=2)
    assert abs(c.ap[-1]) <= c.band


@pytest.mark.parametrize("move", ["parabolic", "trapezoid", "scurve"])
def test_profiled_moves_gather_fe_and_integrator(move):
    c = st.run_move(move, "X", 14336, config=CFG, speed=69632)
    m = st.metrics(c)
    assert c.cp[-1] == 14336 and abs(c.ap[-1] - 14336) <= c.band
    assert 3 < m["max_fe"] < 40  # feed-forward tuned: tens of counts, not thousands
    assert any(c.integ) and len(c.t) == len(c.integ)


def test_compare_two_gain_sets_on_the_same_move(tmp_path, capsys):
    from softplc.cli import main as softplc

    out = tmp_path / "cmp.png"
    assert softplc(["servo", "compare", "I132=0", "--move", "scurve", "--distance", "14336",
                    "--plot", str(out)]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert rows[0].startswith("gains") and rows[2].startswith("I132=0")
    fe_a, fe_b = (float(r.split()[-1]) for r in rows[1:3])
    assert fe_b > 10 * fe_a  # without velocity feed-forward the lag is the velocity's
    assert out.stat().st_size > 20_000


def test_disturbance_plot_and_bad_gains(tmp_path, capsys):
    from softplc.cli import main as softplc

    out = tmp_path / "load.png"
    assert softplc(["servo", "disturb", "--sim", "--load", "150", "--plot", str(out)]) == 0
    assert out.stat().st_size > 20_000
    with pytest.raises(IVarError, match="NAME=VALUE"):
        st.parse_gains(["I130"])
    assert softplc(["servo", "compare", "I130=x"]) == 1
    assert "not a number" in capsys.readouterr().err
