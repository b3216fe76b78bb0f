"""The drawing-table devices: stepper axes, limit switches, pen and trace recorder."""

from __future__ import annotations

import logging
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc.devices import build_devices, device_types
from softplc.errors import ConfigError
from softplc.runtime.memory import MemoryImage

X_PHASES = ["%Q1.0", "%Q1.1", "%Q1.2", "%Q1.3"]
Z_PHASES = ["%Q1.4", "%Q1.5", "%Q1.6", "%Q1.7"]
STRIDE = MemoryImage().stride
X_IDX = [STRIDE + k for k in range(4)]
Z_IDX = [STRIDE + 4 + k for k in range(4)]
PEN_IDX = 14
DT = 0.001


class Rig:
    """A memory image, a set of devices, and a clock stepping one scan at a time."""

    def __init__(self, config: dict):
        self.mem = MemoryImage()
        self.devs = build_devices(config, self.mem)
        self.t = 0.0
        self.n = 0

    def scan(self, dt: float = DT) -> None:
        # t as the engine computes it: scan count * period, no drift
        self.n += 1
        self.t = self.n * dt
        for d in self.devs.values():
            d.update(self.t, dt)

    def phases(self, pattern: str, idx: list[int] = X_IDX, dt: float = DT) -> None:
        """Energise the phases named in `pattern` ("A", "AB", "" for off), then one scan."""
        for k, i in enumerate(idx):
            self.mem.q_field[i] = 1 if "ABCD"[k] in pattern else 0
        self.scan(dt)

    def input(self, address: str) -> bool:
        return bool(self.mem.i_field[self.mem.ref(address).index])


def axis(name: str = "X", phases: list[str] = X_PHASES, **opts) -> dict:
    return {name: {"type": "stepper", "phases": phases, **opts}}


WAVE = ["A", "B", "C", "D"]
FULL = ["AB", "BC", "CD", "DA"]
HALF = ["A", "AB", "B", "BC", "C", "CD", "D", "DA"]


def test_types_registered():
    assert {"stepper", "limit_switch", "pen", "trace"} <= set(device_types())


def test_start_position_rounds_to_a_step():
    rig = Rig(axis(start=10.0))
    x = rig.devs["X"]
    assert x.position == 1111  # 10 * 111.11 = 1111.1
    assert x.position_units == pytest.approx(1111 / 111.11)
    assert x.missed_steps == 0 and x.steps_taken == 0


@pytest.mark.parametrize("start", [0, 5, 1111])
def test_wave_drive_both_directions(start):
    rig = Rig(axis(start=start / 111.11))
    x = rig.devs["X"]
    assert x.position == start
    k = start % 4  # the phase aligned with the rotor: rung 15-18's count REM 4
    rig.phases(WAVE[k])
    assert x.position == start  # holding, no move
    for n in range(1, 10):
        rig.phases(WAVE[(k + n) % 4])
        assert x.position == start + n
    for n in range(1, 15):
        rig.phases(WAVE[(k + 9 - n) % 4])
        assert x.position == start + 9 - n
    assert x.missed_steps == 0
    assert x.steps_taken == 9 + 14


def test_two_phase_full_step_both_directions():
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    rig.phases("AB")  # field half a step ahead of the wave position: rotor settles there
    assert x.position == 0.5
    for n in range(1, 9):
        rig.phases(FULL[n % 4])
        assert x.position == 0.5 + n
    for n in range(1, 5):
        rig.phases(FULL[(8 - n) % 4])
        assert x.position == 8.5 - n
    assert x.missed_steps == 0
    assert x.steps_taken == 0.5 + 8 + 4


def test_half_step_both_directions():
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    for n in range(1, 17):
        rig.phases(HALF[n % 8])
        assert x.position == n / 2
    assert x.position == 8 and isinstance(x.position, int)
    for n in range(1, 12):
        rig.phases(HALF[(16 - n) % 8])
        assert x.position == (16 - n) / 2
    assert x.missed_steps == 0


def test_phase_order_is_the_wiring():
    """Listing the phase outputs in reverse reverses the motor."""
    rig = Rig(axis(phases=list(reversed(X_PHASES))))
    x = rig.devs["X"]
    # outputs %Q1.0, %Q1.1, %Q1.2, %Q1.3 in turn are now phases D, C, B, A
    for n, pattern in enumerate(["A", "B", "C", "D"], start=1):
        rig.phases(pattern)
        assert x.position == -n


def test_opposite_phase_is_a_missed_step(caplog):
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    rig.phases("A")
    with caplog.at_level(logging.WARNING, logger="softplc.devices.stepper"):
        rig.phases("C")
    assert x.position == 0
    assert x.missed_steps == 1
    assert "opposite phase" in x.events[-1][1]
    assert "missed step" in caplog.text
    # the rotor stayed at A: D is one step behind
    rig.phases("D")
    assert x.position == -1 and x.missed_steps == 1


@pytest.mark.parametrize("pattern", ["AC", "BD", "ABC", "ABCD", "BCD"])
def test_impossible_pattern_is_a_missed_step(pattern):
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    rig.phases("A")
    rig.phases(pattern)
    assert x.position == 0 and x.missed_steps == 1
    assert "impossible" in x.events[-1][1]
    rig.phases(pattern)  # unchanged pattern: counted once
    assert x.missed_steps == 1


def test_skipped_half_step_position_still_pulls():
    """A -> BC: the field is 1.5 steps ahead, within reach, the rotor follows."""
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    rig.phases("A")
    rig.phases("BC")
    assert x.position == 1.5 and x.missed_steps == 0


def test_too_fast_loses_steps():
    rig = Rig(axis(start=0.0, max_step_rate=400.0))  # one step per 2.5 ms at most
    x = rig.devs["X"]
    rig.phases("A")
    rig.phases("B")  # t = 2 ms since the start: the first move is always allowed
    assert x.position == 1
    rig.phases("C")  # 1 ms after the last move
    assert x.position == 1 and x.missed_steps == 1
    assert "faster" in x.events[-1][1]
    rig.phases("", dt=DT)
    rig.phases("", dt=DT)
    rig.phases("C")  # 4 ms after the last move, from free: a step
    assert x.position == 2 and x.missed_steps == 1


def test_stepping_at_exactly_the_limit_is_kept():
    rig = Rig(axis(start=0.0, max_step_rate=1000.0))
    x = rig.devs["X"]
    for n in range(1, 1001):
        rig.phases(WAVE[n % 4])
    assert x.position == 1000 and x.missed_steps == 0


def test_half_steps_may_come_twice_as_fast():
    rig = Rig(axis(start=0.0, max_step_rate=500.0))  # 2 ms per step, 1 ms per half step
    x = rig.devs["X"]
    for n in range(1, 9):
        rig.phases(HALF[n % 8])
    assert x.position == 4 and x.missed_steps == 0
    rig.phases("AB")  # half a step, 1 ms later: allowed
    assert x.position == 4.5
    rig.phases("CD")  # opposite of AB: missed
    assert x.missed_steps == 1


def test_all_off_leaves_the_rotor_free():
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    rig.phases("A")
    rig.phases("B")
    rig.phases("")
    for _ in range(5):
        rig.scan()
    assert x.position == 1 and x.missed_steps == 0
    rig.phases("B")  # re-energising the phase the rotor is on: no move
    assert x.position == 1
    rig.phases("")
    rig.phases("C")  # from free, one step ahead
    assert x.position == 2 and x.missed_steps == 0


def test_rotor_is_free_at_power_up():
    """Nothing energised yet: the first phase one step behind pulls the rotor back."""
    rig = Rig(axis(start=0.0))
    rig.phases("D")
    assert rig.devs["X"].position == -1


def test_plc_count_convention():
    """Phase k on for k = count REM 4: +1 on the count is +1 step (rungs 11-18)."""
    rig = Rig(axis(start=1000 / 111.11))
    x = rig.devs["X"]
    count = 1000
    for delta in [1] * 30 + [-1] * 50 + [1] * 7:
        count += delta
        rig.phases(WAVE[count % 4])
    assert x.position == count == 987
    assert x.missed_steps == 0


def test_position_setter():
    rig = Rig(axis(start=0.0))
    x = rig.devs["X"]
    x.position = 12.5
    assert x.position == 12.5 and x._h == 25


def switches(start: float = 0.0, travel: float = 1.0, **switch_opts) -> dict:
    """An axis 1 unit = 10 steps long, with a home and an end switch."""
    return {
        **axis(start=start, steps_per_unit=10.0, travel=travel, hard_stop_margin=0.3),
        "home": {"type": "limit_switch", "axis": "X", "input": "%I0.12", "at": "home",
                 **switch_opts},
        "end": {"type": "limit_switch", "axis": "X", "input": "%I0.13", "at": "end",
                **switch_opts},
    }


def run_to(rig: Rig, target: int) -> None:
    """Wave-drive X from its (whole-step) position to target, one step per scan."""
    x = rig.devs["X"]
    pos = x.position
    step = 1 if target > pos else -1
    rig.phases(WAVE[pos % 4])
    while pos != target:
        pos += step
        rig.phases(WAVE[pos % 4])


def test_limit_switches_home_and_end():
    rig = Rig(switches(start=0.5))
    x = rig.devs["X"]
    # written at bind: the first scan already sees them
    assert not rig.input("%I0.12") and not rig.input("%I0.13")
    run_to(rig, 1)
    assert not rig.input("%I0.12")
    run_to(rig, 0)
    assert rig.input("%I0.12") and rig.devs["home"].made
    run_to(rig, -2)  # past the switch: still made; a switch stops nothing
    assert rig.input("%I0.12") and x.position == -2
    run_to(rig, 9)
    assert not rig.input("%I0.12") and not rig.input("%I0.13")
    run_to(rig, 10)
    assert rig.input("%I0.13") and rig.devs["end"].made
    assert x.missed_steps == 0


def test_end_switch_with_fractional_travel():
    rig = Rig({
        **axis(start=10.0, travel=25.0),
        "end": {"type": "limit_switch", "axis": "X", "input": "%I0.13", "at": "end"},
    })
    x = rig.devs["X"]
    x.position = 2777  # 25 * 111.11 = 2777.75
    rig.scan()
    assert not rig.input("%I0.13")
    x.position = 2778
    rig.scan()
    assert rig.input("%I0.13")


def test_switch_made_at_start_is_visible_at_bind():
    rig = Rig(switches(start=0.0))
    assert rig.input("%I0.12") and not rig.input("%I0.13")


def test_normally_closed_switch():
    rig = Rig(switches(start=0.0, normally_closed=True))
    assert not rig.input("%I0.12")  # made: contact open
    assert rig.input("%I0.13")
    run_to(rig, 3)
    assert rig.input("%I0.12")


def test_stuck_switch_fault():
    rig = Rig(switches(start=0.5, fault="stuck_open"))
    run_to(rig, 0)
    assert not rig.input("%I0.12")
    rig.devs["home"].set_fault("none")
    rig.scan()
    assert rig.input("%I0.12")
    rig.devs["end"].set_fault("stuck_closed")
    rig.scan()
    assert rig.input("%I0.13")


def test_hard_stops_lose_steps():
    rig = Rig(switches(start=0.0))  # stops 0.3 units = 3 steps beyond each end
    x = rig.devs["X"]
    run_to(rig, -3)
    assert x.missed_steps == 0
    rig.phases(WAVE[-4 % 4])
    assert x.position == -3 and x.missed_steps == 1
    assert x.events[-1][1] == "hard stop"
    run_to(rig, 13)
    missed = x.missed_steps
    rig.phases(WAVE[14 % 4])
    assert x.position == 13 and x.missed_steps == missed + 1


def test_homing_like_the_seed_program():
    """Count down from 32000 until the switch is seen a scan later, then count := 0."""
    rig = Rig({
        **axis(start=10.0),
        "home": {"type": "limit_switch", "axis": "X", "input": "%I0.12"},
    })
    x = rig.devs["X"]
    count = 32000
    rig.phases(WAVE[count % 4])  # rotor is free at power-up: it snaps to the first phase
    while not rig.input("%I0.12"):
        count -= 1
        rig.phases(WAVE[count % 4])
    assert x.position == 0
    count = 0
    rig.phases(WAVE[count % 4])
    assert x.position == 0 and x.missed_steps == 0
    for _ in range(100):
        count += 1
        rig.phases(WAVE[count % 4])
    assert x.position == count == 100


def test_pen():
    rig = Rig({"pen": {"type": "pen", "output": "%Q0.14"}})
    pen = rig.devs["pen"]
    assert not pen.down
    rig.mem.q_field[PEN_IDX] = 1
    rig.scan()
    assert pen.down
    rig.mem.q_field[PEN_IDX] = 0
    rig.scan()
    assert not pen.down and pen.moves == 2


def test_pen_delays():
    rig = Rig({"pen": {"type": "pen", "output": "%Q0.14", "lower_delay": "5ms",
                       "lift_delay": "2ms"}})
    pen = rig.devs["pen"]
    rig.mem.q_field[PEN_IDX] = 1
    for _ in range(5):
        rig.scan()
        assert not pen.down
    rig.scan()
    assert pen.down
    rig.mem.q_field[PEN_IDX] = 0
    rig.scan()
    rig.scan()
    assert pen.down
    rig.scan()
    assert not pen.down
    # a blip shorter than the delay does nothing
    rig.mem.q_field[PEN_IDX] = 1
    rig.scan()
    rig.mem.q_field[PEN_IDX] = 0
    for _ in range(10):
        rig.scan()
    assert not pen.down and pen.moves == 2


def table(**trace_opts) -> dict:
    return {
        **axis("X", X_PHASES, start=0.0),
        **axis("Z", Z_PHASES, start=0.0),
        "pen": {"type": "pen", "output": "%Q0.14"},
        "trace": {"type": "trace", "axes": ["X", "Z"], "pen": "pen", **trace_opts},
    }


def draw_square(rig: Rig, side: int = 8) -> None:
    """Pen up to (2, 0), pen down, a square of `side` steps (one axis at a time)."""
    x = z = 0
    rig.phases(WAVE[0], X_IDX)
    rig.phases(WAVE[0], Z_IDX)

    def move(axis_idx, pos, target):
        while pos != target:
            pos += 1 if target > pos else -1
            rig.phases(WAVE[pos % 4], axis_idx)
        return pos

    x = move(X_IDX, x, 2)
    rig.mem.q_field[PEN_IDX] = 1
    rig.scan()
    x = move(X_IDX, x, 2 + side)
    z = move(Z_IDX, z, side)
    x = move(X_IDX, x, 2)
    z = move(Z_IDX, z, 0)
    rig.mem.q_field[PEN_IDX] = 0
    rig.scan()


def test_trace_records_changes_only(tmp_path):
    rig = Rig(table())
    tr = rig.devs["trace"]
    assert tr.samples == [(0.0, 0, 0, 0, 0)]
    for _ in range(50):
        rig.scan()
    assert len(tr.samples) == 1  # nothing changed
    draw_square(rig, 8)
    s = tr.samples
    # 2 pen-up steps, pen down, 4 * 8 drawn steps, pen up
    assert len(s) == 1 + 2 + 1 + 32 + 1
    assert s[2][1:] == (2, 0, 0, 0)
    assert s[3][1:] == (2, 0, 1, 0)
    assert s[3 + 8][1:] == (10, 0, 1, 0)
    assert s[3 + 16][1:] == (10, 8, 1, 0)
    assert s[-1][1:] == (2, 0, 0, 0)
    assert all(b[0] > a[0] for a, b in zip(s, s[1:], strict=False))


def test_trace_records_missed_steps():
    rig = Rig(table())
    rig.phases("A", X_IDX)
    rig.phases("C", X_IDX)
    assert rig.devs["trace"].samples[-1][1:] == (0, 0, 0, 1)


def test_trace_csv(tmp_path):
    rig = Rig(table())
    draw_square(rig, 4)
    tr = rig.devs["trace"]
    path = tmp_path / "trace.csv"
    tr.to_csv(path)
    lines = path.read_text().splitlines()
    assert lines[0] == "t,x,z,pen,missed"
    assert len(lines) == 1 + len(tr.samples)
    assert lines[1] == "0.000000,0,0,0,0"
    t, x, z, pen, missed = lines[-1].split(",")
    assert (x, z, pen, missed) == ("2", "0", "0", "0")
    assert float(t) == pytest.approx(tr.samples[-1][0])


def test_trace_csv_option_written_periodically_and_at_close(tmp_path):
    path = tmp_path / "run.csv"
    rig = Rig(table(csv=str(path), flush_every="5ms"))
    tr = rig.devs["trace"]
    assert not path.exists()
    for pattern in ["A", "B", "C", "D", "A", "B"]:
        rig.phases(pattern, X_IDX)
    assert path.exists()  # flushed at t = 5 ms
    partial = path.read_text().splitlines()
    assert partial[0] == "t,x,z,pen,missed" and 1 < len(partial) < 1 + len(tr.samples)
    tr.close()
    lines = path.read_text().splitlines()
    assert len(lines) == 1 + len(tr.samples) == 1 + 1 + 5
    assert lines[-1].endswith(",5,0,0,0")


def test_trace_max_samples():
    rig = Rig(table(max_samples=3))
    for pattern in ["B", "C", "D", "A"]:
        rig.phases(pattern, X_IDX)
    tr = rig.devs["trace"]
    assert len(tr.samples) == 3 and tr.truncated


@pytest.mark.parametrize("ext", ["png", "svg"])
def test_trace_plot(tmp_path, ext):
    rig = Rig(table())
    draw_square(rig, 8)
    path = tmp_path / f"square.{ext}"
    programmed = [((2, 0), (10, 0)), ((10, 0), (10, 8)), ((10, 8), (2, 8)), ((2, 8), (2, 0))]
    rig.devs["trace"].plot(path, programmed=programmed)
    data = path.read_bytes()
    assert len(data) > 1000
    if ext == "png":
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
    else:
        assert b"<svg" in data[:2000]
    path2 = tmp_path / f"square_units.{ext}"
    rig.devs["trace"].plot(path2, units="units")
    assert path2.stat().st_size > 1000


def test_trace_plot_bad_extension(tmp_path):
    rig = Rig(table())
    with pytest.raises(ConfigError, match=r"\.png or \.svg"):
        rig.devs["trace"].plot(tmp_path / "x.jpg")


@pytest.mark.parametrize("config, message", [
    (axis(phases=["%Q1.0", "%Q1.1", "%Q1.2"]), "devices.X.phases: list should have at least 4"),
    (axis(phases=["%Q1.0", "%Q1.1", "%Q1.2", "%Q1.2"]), "distinct"),
    (axis(phases=["%Q1.0", "%Q1.1", "%Q1.2", "%I0.3"]),
     r"devices.X.phases\[3\]: expected a %Q bit address"),
    (axis(phases=["%Q1.0", "%Q1.1", "%Q1.2", "%Q9.0"]), "module 9"),
    (axis(steps_per_unit=0), "devices.X.steps_per_unit: expected greater than 0"),
    (axis(start=30.0), "beyond the hard stops"),
    (axis(bogus=1), "devices.X.bogus: unknown key; known: direction, hard_stop_margin"),
    (axis(travel="25"), r"devices.X.travel: expected a valid number \(got '25'\)"),
    (axis(max_step_rate=math.nan),
     "devices.X.max_step_rate: expected greater than 0 \\(got nan\\)"),
    ({"p": {"type": "pen", "output": "%Q0.14", "lift_delay": 0.5}}, "bare number"),
    ({**axis(), "s": {"type": "limit_switch", "axis": "Y", "input": "%I0.12"}},
     "not a stepper"),
    ({**axis(), "s": {"type": "limit_switch", "axis": "X", "input": "%I0.12", "at": "mid"}},
     "home"),
    ({**axis(), "s": {"type": "limit_switch", "axis": "X", "input": "%Q0.1"}},
     "devices.s.input: expected a %I bit address"),
    ({"p": {"type": "pen", "output": "%Q0.14", "lift_delay": "-1ms"}},
     "devices.p.lift_delay: not a duration"),
    ({**axis(),
     "t": {"type": "trace", "axes": ["X"]}}, "devices.t.axes: list should have at least 2"),
    ({**axis(), **axis("Z", Z_PHASES), "t": {"type": "trace", "pen": "nib"}}, "not a pen"),
])
def test_config_errors(config, message):
    with pytest.raises(ConfigError, match=message):
        build_devices(config, MemoryImage())


def test_reset():
    rig = Rig(table())
    draw_square(rig, 4)
    rig.phases("A", X_IDX)  # X rests at 2 (phase C): A is opposite, a missed step
    assert rig.devs["X"].missed_steps == 1
    for d in rig.devs.values():
        d.reset()
    x, tr = rig.devs["X"], rig.devs["trace"]
    assert x.position == 0 and x.missed_steps == 0 and x.steps_taken == 0
    assert not rig.devs["pen"].down
    assert tr.samples == [(0.0, 0, 0, 0, 0)]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([1, -1]), max_size=300), st.integers(0, 3))
def test_random_wave_sequences_track_exactly(directions, gap):
    """Valid +-1 wave patterns at a legal rate: position = start + sum, nothing missed."""
    rig = Rig(axis(start=10.0))  # 1111 steps, far from the stops
    x = rig.devs["X"]
    count = 1111
    rig.phases(WAVE[count % 4])
    for d in directions:
        for _ in range(gap):  # scans with the pattern held
            rig.scan()
        count += d
        rig.phases(WAVE[count % 4])
    assert x.position == 1111 + sum(directions)
    assert x.missed_steps == 0
    assert x.steps_taken == len(directions)
