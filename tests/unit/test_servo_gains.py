"""Issue 31 item 7: each I-variable within its PMAC range (law.RANGES), refused beyond on
every path (Python, the axis's Modbus words, the `softplc servo` command line), and the
fatal following error (Ixx11) stopping an axis that a destabilising gain makes diverge."""

from __future__ import annotations

import math

import pytest
from daemon_util import ROOT

from softplc.devices.axis import Ctl, Err, St, Word
from softplc.devices.axis import ivars as iv
from softplc.devices.axis.law import I24_MAX, IVARS, RANGES, Gains
from softplc.devices.axis.rig import Rig
from softplc.errors import ConfigError
from softplc.machines.servo.client import ServoClientError, parse_ivars

TOML = ROOT / "ladder_programs" / "servo_table.toml"
HUGE = (1e30, 3.4e38)  # the gains: accepted live before, nothing said what then


def homed(**over: object) -> Rig:
    """The servo table's X axis, loop closed and homed at -50,000 counts."""
    rig = Rig.from_toml(TOML, "X", require_home=False, start=-50000.0, **over)
    rig.command("X", Ctl.ENABLE)
    rig.run(0.05)
    dev = rig.axes["X"]
    dev.homed = True
    dev.origin = -dev._enc0
    rig.step()
    return rig


@pytest.mark.parametrize(("ivar", "name"), [(i, n) for i, n, _, _ in IVARS
                                            if i not in iv.CONFIG_ONLY])
def test_each_ivar_accepts_its_range_and_refuses_beyond(ivar, name):
    lo, hi, open_lo, source = RANGES[ivar]
    assert source  # every row names where its range comes from
    assert getattr(iv.check(Gains(), ivar, hi), name) == hi
    with pytest.raises(iv.IVarError, match=f"{ivar} \\({name}\\).*less than or equal"):
        iv.check(Gains(), ivar, hi + 1)
    if open_lo:
        with pytest.raises(iv.IVarError, match="greater than"):
            iv.check(Gains(), ivar, lo)
    else:
        assert getattr(iv.check(Gains(), ivar, lo), name) == lo
        with pytest.raises(iv.IVarError, match="greater than or equal"):
            iv.check(Gains(), ivar, lo - 1)
    for value in (*HUGE, -HUGE[1], math.inf, math.nan):
        with pytest.raises(iv.IVarError):
            iv.check(Gains(), ivar, value)


def test_a_configuration_beyond_a_range_is_a_clear_error():
    with pytest.raises(ConfigError, match=r"ivars\.Ixx30.*less than or equal to 8388607"):
        Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0}, "ivars": {"Ixx30": 1e30}}})
    with pytest.raises(ConfigError, match=r"ivars\.Ixx11.*less than or equal to 8388607"):
        Rig({"X": {"type": "servo_axis", "plant": {"K": 1.0}, "ivars": {"Ixx11": 1e30}}})


def test_huge_gains_are_refused_live_from_python():
    rig = homed()
    dev = rig.axes["X"]
    kp = dev.gains.kp
    for value in HUGE:
        with pytest.raises(iv.IVarError, match="Ixx30 \\(kp\\).*less than or equal to 8388607"):
            dev.ivars.set("kp", value)
    rig.step()
    assert dev.gains.kp == kp


def test_huge_gains_written_to_the_axis_words_are_refused_and_named():
    """A Modbus host (or the web monitor's animation table) writes %MF words of the table:
    the axis refuses each, names the I-variable in the REFUSED word and writes back the
    value in force."""
    rig = homed()
    dev = rig.axes["X"]
    at = dev.ivars._at
    row = next(k for k, (i, *_) in enumerate(IVARS) if i == "Ixx30")
    mf = at + iv.FIRST + 2 * row  # %MF328 of servo_table.toml
    kp = dev.gains.kp
    for value in HUGE:
        rig.mem.mw.set_f(mf, value)
        assert rig.mem.mw.get_f(mf) == pytest.approx(value, rel=1e-6)  # float32 holds it
        rig.step(2)
        assert dev.gains.kp == kp
        assert rig.mem.mw.uw[at + iv.REFUSED] == 30
        assert rig.mem.mw.get_f(mf) == kp  # the value in force, written back
    rig.mem.mw.set_f(mf, I24_MAX)  # the largest in range is taken
    rig.step(2)
    assert dev.gains.kp == I24_MAX and rig.mem.mw.uw[at + iv.REFUSED] == 0


@pytest.mark.parametrize("item", ["I169=1e300", "I130=1e30", "I130=3.4e38", "I111=-1"])
def test_the_command_line_refuses_out_of_range_values_before_sending(item):
    """`softplc servo set I169=1e300` raised OverflowError (packing a float32); now the
    value is checked against the range first, with the I-variable in the message."""
    with pytest.raises(ServoClientError, match=item.split("=")[0]):
        parse_ivars([item], values=True)


def test_a_destabilising_gain_in_range_trips_the_fatal_following_error():
    """Ixx33 at its largest (with Ixx63 letting the integrator run): the loop oscillates
    with a growing following error until it passes Ixx11 (65,536 / 16 = 4,096 counts);
    the axis is killed (output 0, loop open), the error words say FATAL_FE, latched."""
    rig = homed()
    dev = rig.axes["X"]
    dev.ivars.set("ki", I24_MAX)
    dev.ivars.set("int_limit", I24_MAX)
    rig.step()
    assert dev.gains.ki == I24_MAX
    rig.pulse("X", Ctl.EXECUTE, target=-40000, speed=69632)
    peaks = []
    while not rig.word("X", Word.ERROR) and rig.t < 2.0:
        rig.step()
        peaks.append(abs(dev.fe))
    assert rig.word("X", Word.ERROR) == Err.FATAL_FE
    st = rig.word("X", Word.STATUS)
    assert st & St.FE_FATAL and not st & St.ENABLED
    assert rig.word("X", Word.OUTPUT, "f") == 0.0 and not dev.closed
    fatal = dev.gains.fatal_fe / 16
    assert fatal < rig.word("X", Word.FE_MAX, "f") < 1.1 * fatal
    assert max(peaks[: len(peaks) // 2]) < fatal / 2  # it grew: not a jump at the start
    rig.run(0.5)
    assert rig.word("X", Word.STATUS) & St.FE_FATAL and not dev.closed  # latched


def test_the_docs_page_shows_the_range_table():
    from softplc.devices.axis.law import range_table

    assert range_table() in (ROOT / "docs" / "servo-gains.md").read_text(encoding="utf-8")
