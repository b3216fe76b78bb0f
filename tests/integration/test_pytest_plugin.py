"""The pytest plugin (softplc.testing, entry point pytest11): the `plc` fixture with
@pytest.mark.plc_program, the `plc_from_source` factory, and the pulse / scan_until
helpers; both used directly here and in a separate pytest run (pytester).
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.testing import pulse, scan_until

pytest_plugins = ["pytester"]

MOTOR = """\
(* start / stop with self-hold *)
LD    %I0.0
OR    %Q0.0
ANDN  %I0.1
ST    %Q0.0
LD    %Q0.0
IN    %TM0
LD    %TM0.Q
ST    %Q0.1
"""

MOTOR_TOML = """\
scan_period = "10ms"
[timers."%TM0"]
type = "TON"
base = "100ms"
preset = 5
"""


# ---- used directly --------------------------------------------------------------------------
@pytest.mark.plc_program("ladder_programs/drawing_table.il",
                         config="ladder_programs/drawing_table.toml")
def test_plc_fixture_loads_a_program_relative_to_the_root(plc):
    assert isinstance(plc, PLC)
    assert plc.scan_count == 0 and plc.state == "RUN"
    plc.scan(3)
    assert plc.scan_count == 3
    assert plc.rungs


def test_plc_from_source_factory(plc_from_source):
    plc = plc_from_source(MOTOR, {"timers": {"%TM0": {"type": "TON", "base": "100ms",
                                                       "preset": 5}}})
    pulse(plc, "%I0.0")
    assert plc["%Q0.0"] and not plc["%Q0.1"]
    scan_until(plc, lambda p: p["%Q0.1"], timeout=1)
    assert 0.45 <= plc.time <= 0.6
    pulse(plc, "%I0.1")
    assert not plc["%Q0.0"] and not plc["%Q0.1"]


def test_plc_from_source_gives_independent_plcs(plc_from_source):
    a = plc_from_source("LD 1\n[ INC %MW0 ]\n")
    b = plc_from_source("LD 1\n[ INC %MW0 ]\n")
    a.scan(3)
    assert a["%MW0"] == 3 and b["%MW0"] == 0


def test_pulse_holds_for_n_scans(plc_from_source):
    plc = plc_from_source("LD %I0.0\n[ INC %MW0 ]\n")
    pulse(plc, "%I0.0", scans=4)
    assert plc["%MW0"] == 4 and not plc["%I0.0"]


# ---- in a separate pytest run ---------------------------------------------------------------
def test_plugin_in_a_user_project(pytester):
    pytester.makefile(".il", motor=MOTOR)
    pytester.makefile(".toml", motor=MOTOR_TOML)
    pytester.makepyfile(test_motor="""
import pytest
from softplc.testing import pulse, scan_until

@pytest.mark.plc_program("motor.il", config="motor.toml")
def test_start_stop(plc):
    pulse(plc, "%I0.0")
    assert plc["%Q0.0"]
    scan_until(plc, lambda p: p["%Q0.1"], timeout=1.0)
    pulse(plc, "%I0.1")
    assert not plc["%Q0.0"]

@pytest.mark.plc_program("motor.il", "motor.toml")
def test_positional_config(plc):
    assert plc.scan_period == 0.01

def test_inline(plc_from_source):
    plc = plc_from_source("LD %I0.0\\nST %Q0.0\\n")
    pulse(plc, "%I0.0")
    assert not plc["%Q0.0"]

@pytest.mark.plc_program("motor.il", config="motor.toml")
def test_times_out(plc):
    scan_until(plc, lambda p: p["%Q0.1"], timeout=0.2)

def test_needs_the_marker(plc):
    pass
""")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=3, failed=1, errors=1)  # a fixture failure is an error
    result.stdout.fnmatch_lines([
        "*condition not met within 0.2 s of PLC time*",
    ])
    result.stdout.fnmatch_lines(["*needs @pytest.mark.plc_program*"])


def test_plugin_reports_program_errors_clearly(pytester):
    pytester.makefile(".il", bad="LD %M0\nST %I0.0\n")
    pytester.makepyfile(test_bad="""
import pytest

@pytest.mark.plc_program("bad.il")
def test_bad(plc):
    pass
""")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*bad.il:2:1: cannot write %I0.0*"])


def test_plugin_registers_the_marker(pytester):
    result = pytester.runpytest("--markers")
    result.stdout.fnmatch_lines(["*plc_program(path, config=None)*"])


def test_marker_paths_are_relative_to_the_test_file(pytester):
    """`pytest sub/test_motor.py` from another folder (rootdir elsewhere too) finds the
    program next to the test file; a missing program is named with that folder."""
    pytester.makeini("[pytest]\n")  # rootdir = pytester.path, not the test's folder
    sub = pytester.mkdir("sub")
    (sub / "motor.il").write_text(MOTOR)
    (sub / "motor.toml").write_text(MOTOR_TOML)
    (sub / "test_motor.py").write_text("""
import pytest

@pytest.mark.plc_program("motor.il", config="motor.toml")
def test_found(plc):
    assert plc.scan_period == 0.01

@pytest.mark.plc_program("absent.il")
def test_missing(plc):
    pass
""")
    result = pytester.runpytest("-p", "no:cacheprovider", "sub/test_motor.py")
    result.assert_outcomes(passed=1, errors=1)
    result.stdout.fnmatch_lines([f"*{sub / 'absent.il'}*"])


def test_plc_factory_gives_each_hypothesis_example_a_fresh_plc(pytester):
    """`plc_factory` with @given: no function-scoped-fixture health check, a cold-started
    PLC per example (the counter starts at 0 every time), the module's marker as the
    default program, and a failing example shows the outputs on by symbol (issue 33)."""
    pytester.makefile(".il", motor=MOTOR + "LD %I0.2\n[ INC %MW0 ]\n")
    pytester.makefile(".toml", motor=MOTOR_TOML + '[symbols]\nMOTOR = "%Q0.0"\n'
                                                  'START_PB = "%I0.0"\nCOUNT = "%MW0"\n')
    pytester.makepyfile(test_prop="""
import pytest
from hypothesis import given, settings, strategies as st

pytestmark = pytest.mark.plc_program("motor.il", config="motor.toml")
seen = []

@settings(max_examples=25, deadline=None)
@given(st.integers(0, 20))
def test_fresh_per_example(plc_factory, n):
    with plc_factory() as plc:
        assert plc.scan_count == 0 and plc["COUNT"] == 0
        plc["%I0.2"] = 1
        plc.scan(n)
        assert plc["COUNT"] == n
    seen.append(n)

def test_examples_ran():
    assert len(seen) > 1

@settings(max_examples=5, deadline=None)
@given(st.just(1))
def test_fails_with_symbols(plc_factory, n):
    with plc_factory("motor.il", "motor.toml") as plc:
        plc["START_PB"] = n
        plc.scan()
        assert not plc["MOTOR"], plc
""")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=2, failed=1)
    result.stdout.fnmatch_lines(["*on: START_PB(%I0.0) MOTOR(%Q0.0)>*"])
    result.stdout.no_fnmatch_line("*function_scoped_fixture*")
