"""The example programs in ladder_programs/, tested the way a user tests ladder logic:
with the softplc pytest plugin (`plc_program` marker, `plc` fixture) on the virtual clock."""

from __future__ import annotations

import pytest
from fuzz_budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc import PLC
from softplc.testing import pulse

TRAFFIC = pytest.mark.plc_program("ladder_programs/traffic_light.il",
                                  config="ladder_programs/traffic_light.toml")
STAR_DELTA = pytest.mark.plc_program("ladder_programs/star_delta.il",
                                     config="ladder_programs/star_delta.toml")


def lights(plc: PLC) -> str:
    cars = "G" if plc["%Q0.0"] else "Y" if plc["%Q0.1"] else "R" if plc["%Q0.2"] else "-"
    walk = "walk" if plc["%Q0.3"] else "dont" if plc["%Q0.4"] else "dark"
    return f"{cars} {walk}"


@TRAFFIC
def test_traffic_light_stays_green_without_a_request(plc):
    plc.run(seconds=60)
    assert lights(plc) == "G dont" and plc["%X0"] and not plc["%Q0.5"]


@TRAFFIC
def test_traffic_light_cycle_after_a_request(plc):
    plc.scan()
    pulse(plc, "%I0.0")
    assert plc["%Q0.5"]  # the wait lamp shows the stored request
    plc.run(seconds=9.5)
    assert lights(plc) == "G dont"  # minimum green: 10 s from the cold start
    plc.run(seconds=1.0)
    assert lights(plc) == "Y dont"
    plc.run(seconds=3.0)
    assert lights(plc) == "R walk" and not plc["%Q0.5"]  # request served
    plc.run(seconds=8.0)
    assert plc["%X3"] and plc["%Q0.2"] and not plc["%Q0.3"]  # clearance
    blink = set()
    for _ in range(100):  # don't walk blinks on %S5 (100 ms clock) during the clearance
        plc.scan()
        blink.add(plc["%Q0.4"])
    assert blink == {True, False}
    plc.run(seconds=3.0)
    assert lights(plc) == "G dont" and plc["%C0.V"] == 1


@TRAFFIC
def test_traffic_light_ignores_presses_while_pedestrians_cross(plc):
    plc.scan()
    pulse(plc, "%I0.0")
    plc.run(seconds=14)
    assert lights(plc) == "R walk"
    pulse(plc, "%I0.0")  # pressing during walk stores nothing
    plc.run(seconds=12)
    assert lights(plc) == "G dont" and not plc["%Q0.5"]
    plc.run(seconds=30)
    assert lights(plc) == "G dont"


def run_ok(plc: PLC) -> None:
    plc["%I0.1"] = 1  # stop button not pressed (NC)
    plc["%I0.2"] = 1  # overload relay OK (NC)


@STAR_DELTA
def test_star_then_delta(plc):
    run_ok(plc)
    pulse(plc, "%I0.0")
    assert (plc["%Q0.0"], plc["%Q0.1"], plc["%Q0.2"], plc["%MW11"]) == (True, True, False, 1)
    plc.run(seconds=4.8)
    assert plc["%Q0.1"] and not plc["%Q0.2"]
    plc.run(seconds=0.5)
    assert plc["%Q0.0"] and not plc["%Q0.1"] and plc["%Q0.2"] and plc["%MW11"] == 3
    assert plc["%MW10"] == 1  # one start counted


@STAR_DELTA
def test_overload_trips_and_needs_a_reset(plc):
    run_ok(plc)
    pulse(plc, "%I0.0")
    plc.run(seconds=6)
    plc["%I0.2"] = 0
    plc.scan()
    assert not (plc["%Q0.0"] or plc["%Q0.1"] or plc["%Q0.2"]) and plc["%MW11"] == 9
    plc["%I0.2"] = 1
    pulse(plc, "%I0.0")  # start refused until the fault is reset
    assert not plc["%Q0.0"]
    pulse(plc, "%I0.3")
    pulse(plc, "%I0.0")
    assert plc["%Q0.0"] and plc["%MW10"] == 2


# Safety property: whatever the operator and the overload relay do, star and delta are never
# on together, and neither is on without the main contactor.
event = st.tuples(st.sampled_from(["start", "stop", "overload", "ok", "reset", "wait"]),
                  st.integers(1, 700))  # then that many 10 ms scans


@settings(max_examples=examples(60), deadline=None)
@given(st.lists(event, max_size=12))
def test_star_and_delta_never_together(plc_factory, events):
    # plc_factory (softplc.testing): a fresh, cold-started PLC per hypothesis example
    with plc_factory("ladder_programs/star_delta.il",
                     "ladder_programs/star_delta.toml") as plc:
        _star_delta_events(plc, events)


def _star_delta_events(plc: PLC, events: list[tuple[str, int]]) -> None:
    """The events on the star-delta starter, by the symbols of star_delta_symbols.csv."""
    run_ok(plc)
    for what, scans in events:
        if what in ("start", "reset"):
            plc["START_PB" if what == "start" else "FAULT_RESET"] = 1
        elif what == "stop":
            plc["STOP_PB"] = 0  # NC: 0 = pressed
        elif what in ("overload", "ok"):
            plc["OVERLOAD_OK"] = 0 if what == "overload" else 1
        for _ in range(scans):
            plc.scan()
            km1, star, delta = plc["KM1_MAIN"], plc["KM2_STAR"], plc["KM3_DELTA"]
            assert not (star and delta), plc
            assert km1 or not (star or delta), plc
            if not plc["OVERLOAD_OK"]:
                assert not km1, plc
        plc["START_PB"] = plc["FAULT_RESET"] = 0
        plc["STOP_PB"] = 1
