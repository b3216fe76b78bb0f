"""Issue 11 B: the Twido PID function `[ PID n ]` and its auto-tuning, on the simulated
oven (first order plus dead time), and the example ladder_programs/pid_oven.il.

Sources: auto-tuning preconditions from Schneider FAQ FA213467 ("open-loop, stable
system", "steady state with a null process input" at the start, no disturbance, periodic
scan with Ts an exact multiple of the scan period) [manual]; parameter units and the
0..10000 output range from TWD USE 10AE / the TwidoSuite PID quick start guide (from
memory, see docs/twido.md#pid). The control law, the identification and the tuning rule are
our choices (softplc/runtime/pid.py), and so are the tolerances below: no Twido document
found gives closed-loop tolerances.
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.errors import ConfigError, ProgramError
from softplc.runtime.pid import D_AT_DONE, D_AT_FAILED, D_LIMITED, D_MANUAL, D_NOT_STEADY, D_PARAM

EXAMPLE = ("ladder_programs/pid_oven.il", "ladder_programs/pid_oven.toml")
GAIN, TAU, DEAD = 300.0, 120.0, 10.0  # the example's oven


def oven_plc(pid: dict, *, oven: dict | None = None, period: str = "100ms",
             src: str = "LD 1\n[ PID 0 ]\n") -> PLC:
    cfg = {"scan_period": period, "modules": {2: "TWDALM3LT"},
           "analog": {"%IW2.0": {"type": "PT100", "range": "celsius"},
                      "%QW2.0": {"type": "0-10V", "range": "custom", "min": 0,
                                 "max": 10000}},
           "pid": {"0": {"measure": "%IW2.0", "setpoint": "%MW10", "output": "%QW2.0",
                         "diagnostic": "%MW30", "measure_span": 8000, **pid}},
           "devices": {"oven": {"type": "oven", "sensor": "%IW2.0", "heater": "%QW2.0",
                                "gain": GAIN, "tau": TAU, "dead_time": DEAD, **(oven or {})}}}
    return PLC.from_source(src, cfg)


def test_autotune_identifies_the_oven_and_regulates():
    plc = PLC.from_file(*EXAMPLE)
    pid = plc.mem.blocks["PID"][0]
    assert plc.run_until(lambda p: p["%MW30"] & D_AT_DONE, timeout=1800)
    r = pid.p.at_result
    assert r["K"] == pytest.approx(GAIN * 10 / 10000, rel=0.05)   # tenths per output unit
    assert r["T"] == pytest.approx(TAU, rel=0.05)
    assert r["L"] == pytest.approx(DEAD, rel=0.15)
    assert plc["%MW20"] == round(r["Kp"] * 100) and plc["%MW21"] == round(r["Ti"] * 10)
    plc.run(900)
    assert plc["%IW2.0"] == pytest.approx(1500, abs=5) and plc["%Q0.0"]


def test_closed_loop_step_response_after_autotune():
    plc = PLC.from_file(*EXAMPLE)
    plc.run_until(lambda p: p["%MW30"] & D_AT_DONE, timeout=1800)
    plc.run(1200)                                  # settled at 150.0 degrees
    plc["%MW10"] = 2000                            # a 50-degree set-point step
    temps = []
    for _ in range(1800):
        plc.run(1)
        temps.append(plc.devices["oven"].temperature)
    overshoot = max(temps) - 200.0
    assert overshoot < 0.10 * 50, f"overshoot {overshoot:.1f} degrees"
    settle = next(k for k in range(len(temps)) if all(abs(t - 200) < 1 for t in temps[k:]))
    assert settle < 6 * TAU, f"settled after {settle} s"


def test_autotune_needs_a_steady_process_at_the_start():
    plc = oven_plc({"mode": "AT+PID"}, oven={"start": 300.0})  # a hot oven, cooling down
    plc.run(10)
    assert plc["%MW30"] & D_AT_FAILED and plc["%MW30"] & D_NOT_STEADY
    assert plc["%QW2.0"] == 0


def test_autotune_can_run_again_once_the_process_is_steady():
    plc = oven_plc({"mode": "AT"}, oven={"start": 300.0})
    plc.run(10)
    assert plc["%MW30"] & D_AT_FAILED
    plc.run(3000)                                          # back at ambient
    plc.mem.blocks["PID"][0].start_autotune()
    assert plc.run_until(lambda p: p["%MW30"] & D_AT_DONE, timeout=1800)
    plc.run(5)
    assert plc["%QW2.0"] == 0, "AT alone does not regulate"


def test_manual_mode_and_bumpless_return():
    plc = oven_plc({"kp": 1900, "ti": 830, "manual": "%M0", "manual_output": "%MW31"})
    plc["%MW10"] = 1000
    plc.run(1500)
    assert plc["%IW2.0"] == pytest.approx(1000, abs=5)
    auto_out = plc["%QW2.0"]
    plc["%M0"], plc["%MW31"] = 1, auto_out
    plc.run(5)
    assert plc["%MW30"] & D_MANUAL and plc["%QW2.0"] == auto_out
    plc["%MW31"] = 0
    plc.run(2)
    assert plc["%QW2.0"] == 0
    plc["%MW31"] = auto_out
    plc.run(2)
    plc["%M0"] = 0
    plc.run(2)
    assert abs(plc["%QW2.0"] - auto_out) < 300, "no bump when going back to automatic"


def test_output_limits():
    plc = oven_plc({"kp": 1900, "ti": 830, "output_max": 3000})
    plc["%MW10"] = 2500
    plc.run(60)
    assert plc["%QW2.0"] == 3000 and plc["%MW30"] & D_LIMITED


def test_direct_action_cools():
    # a cooler: more output, lower temperature; direct action: e = PV - SP
    plc = oven_plc({"kp": 500, "ti": 600, "action": "direct"},
                   oven={"gain": -100.0, "ambient": 60.0, "tau": 60.0, "dead_time": 2.0})
    plc["%MW10"] = 300
    plc.run(900)
    assert plc["%IW2.0"] == pytest.approx(300, abs=5)
    assert 0 < plc["%QW2.0"] < 10000


def test_pwm_output_drives_a_heater_bit():
    cfg_oven = {"heater": None, "heater_bit": "%Q0.0"}
    plc = oven_plc({"kp": 1900, "ti": 830, "pwm_output": "%Q0.0", "pwm_period": 200,
                    "output": None}, oven=cfg_oven)
    plc["%MW10"] = 1000
    plc.run(1500)
    assert plc["%IW2.0"] == pytest.approx(1000, abs=15)
    u = plc.mem.blocks["PID"][0].u
    on = 0
    for _ in range(20):                               # one 2 s PWM period
        plc.scan()
        on += plc["%Q0.0"]
    assert on / 20 == pytest.approx(u / 10000, abs=0.1)


def test_ts_must_be_a_multiple_of_the_scan_period():
    plc = oven_plc({"ts": 15})                        # 150 ms on a 100 ms scan
    plc.scan()
    assert plc["%MW30"] & D_PARAM


def test_cold_start_restarts_the_autotuning():
    plc = PLC.from_file(*EXAMPLE, devices=False)
    plc.mem.analog.set_input("%IW2.0", 20.0)
    plc.run(8)
    assert plc["%QW2.0"] == 5000, "the AT step"
    plc.cold_start()
    plc.scan()
    assert plc["%QW2.0"] == 0, "back to the steady-state check"


@pytest.mark.parametrize("pid, message", [
    ({"kp": 100, "kpp": 3}, "pid.0.kpp: unknown key; known: action"),
    ({"kp": "%MF4"}, "pid.0.kp: '%MF4' is not a word"),
    ({"output": "%IW2.1"}, "pid.0.output: '%IW2.1' cannot be written"),
    ({"mode": "AUTO"}, "pid.0.mode"),
    ({"manual": "%MW3"}, "pid.0.manual: '%MW3' is not a"),
    ({"output_min": 5000, "output_max": 100}, "output_min > output_max"),
])
def test_config_errors(pid, message):
    with pytest.raises(ConfigError) as e:
        oven_plc(pid)
    assert message in str(e.value)


@pytest.mark.parametrize("src, message", [
    ("LD 1\n[ PID 1 ]\n", "PID 1 is used but not configured"),
    ("LD 1\n[ PID 20 ]\n", "PID 20 beyond PID 0 .. PID 13"),
])
def test_program_errors(src, message):
    with pytest.raises(ProgramError) as e:
        oven_plc({}, src=src)
    assert message in str(e.value)


def test_pid_shows_in_the_ladder_view():
    from softplc.ladder import render_text

    plc = oven_plc({})
    text = render_text(plc.ast.rungs[0])
    assert "[ PID 0 ]" in text


def test_repl_lists_pids_and_analog_channels():
    from softplc.debug.session import Session

    s = Session(PLC.from_file(*EXAMPLE), EXAMPLE[0])
    s.execute("run 30s")
    out = s.execute("pid")
    assert "PID 0" in out and "AT+PID" in out and "AT=step" in out and "OUT=5000" in out
    out = s.execute("analog")
    assert "%IW2.0   PT100  celsius" in out and "%QW2.0   0-10V  custom 0..10000    5000" in out


def test_retained_state_carries_the_pid_over_a_warm_restart(tmp_path):
    from softplc.persist import retain

    plc = PLC.from_file(*EXAMPLE)
    plc.run_until(lambda p: p["%MW30"] & D_AT_DONE, timeout=1800)
    plc.run(600)
    retain.save(tmp_path / "pid.state", retain.capture(plc.mem))
    again = PLC.from_file(*EXAMPLE, devices=False)
    retain.apply(again.mem, retain.load(tmp_path / "pid.state"))
    again.warm_start()
    again.mem.analog.set_input("%IW2.0", 149.0)
    again.scan()
    pid = again.mem.blocks["PID"][0]
    assert pid._at == "done" and again["%MW20"] == plc["%MW20"]
    assert abs(again["%QW2.0"] - plc["%QW2.0"]) < 500, "regulation goes on from the output"
