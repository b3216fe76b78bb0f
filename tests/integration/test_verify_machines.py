"""The machines' requirement files (issue 34 item 3): counterexamples `softplc verify`
found in the shipped programs, kept as tests once the program was fixed, and the quick
proofs of the servo cell (the slow ones: tools/bench_verify.py --machines)."""

from __future__ import annotations

from pathlib import Path

from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.replay import first_failure, set_inputs

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"


def test_mass_tuning_amber_lamp_off_in_fault():
    """VIOLATED before the fix, in 2 scans: the softkey in automatic mode starts the
    measurement, automatic mode lost in the next scan sends it to FAULT (step 40), and the
    amber lamp, computed from the scan's first steps, stayed lit in that scan."""
    scans = [{"%I0.0": 1, "%I0.1": 1}, {"%I0.0": 0, "%I0.1": 0}]
    with PLC.from_file(LP / "mass_tuning.il", LP / "mass_tuning.toml", devices=False) as plc:
        assert first_failure(plc, "never %X40 AND %Q0.2", scans) is None
        assert plc["%X40"] == 1  # the fault did happen: the lamp is what changed


# Found by verify (29 scans, replayed in the engine): a press in the scan in which the
# clearance ends and the chart returns to step 0. The press rung ran before the chart (it
# saw step 3), the scan ended in step 0 with the lamp off: the press was lost. The rung
# is now in POST, after the chart.
PRESS_PERIODS = ([1000] * 10 + [430, 1000, 1000, 1000, 10] + [1000] * 8
                 + [300, 1000, 1000, 1000, 110, 320])  # ms, each scan's (a free period)
PRESS_SCANS = [12, 23, 29]
PRESS_AT_GREEN = "%I0.0 rising -> %Q0.5 OR NOT %X0 within 0 scans"


def test_traffic_light_keeps_a_press_at_the_return_to_green():
    scans = [{"%I0.0": int(n in PRESS_SCANS), "period_ms": ms}
             for n, ms in enumerate(PRESS_PERIODS, 1)]
    shipped = (LP / "traffic_light.il").read_text()
    rung = "LDR   %I0.0\nAND   %X0\nS     %M0\n\n"
    before = shipped.replace(rung, "").replace("=*= 0\n", rung + "=*= 0\n", 1)
    assert before != shipped
    config = LP / "traffic_light.toml"
    with PLC.from_source(before, config, devices=False) as plc:  # verify's counterexample
        assert first_failure(plc, PRESS_AT_GREEN, scans) == len(scans)
        assert plc["%X0"] == 1 and plc["%Q0.5"] == 0  # back to green, the press lost

    def cycle(text: str, presses: set[int]) -> tuple[int, int]:
        """A press at scan 2 starts a crossing (1 s scans); the scan in which the chart is
        back in step 0, and the wait lamp after it, with `presses`."""
        with PLC.from_source(text, config, devices=False) as plc:
            left = False
            for n in range(1, 200):
                set_inputs(plc, {"%I0.0": int(n in presses), "period_ms": 1000})
                plc.scan()
                left = left or not plc["%X0"]
                if left and plc["%X0"]:
                    return n, plc["%Q0.5"]
        raise AssertionError("the crossing did not end")
    for text, lit in ((before, 0), (shipped, 1)):
        back, _ = cycle(text, {2})
        assert cycle(text, {2, back}) == (back, lit)


def test_servo_cell_requirements_proven(capsys):
    args = ["verify", str(LP / "servo_table.il"), "--config", str(LP / "servo_table.toml"),
            "--require", str(LP / "servo_table.req.toml"), "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("PROVEN") == 3
    assert "free, written by device X" in out  # the drives' status words


# The cutting table: home, a fault (E-stop), an offer written during it, RESET, READY.
# Axis status words (servo_axis): X0 ENABLED, X2 IN_POS, X3 DONE (docs/machines/
# servo-table.md); the min switches %I0.8 / %I0.10 end the homing search.
ENABLED, AT_REST = 1, 1 + 4 + 8
AXES_AT_REST = {"%MW218": AT_REST, "%MW248": AT_REST}
FAULT_OFFER = [
    {"%I0.16": 1, "%MW218": ENABLED, "%MW248": ENABLED},        # INIT -> HOME_SEARCH
    {"%I0.8": 1, "%I0.10": 1},                                  # both min switches: zeroed
    {"%I0.8": 0, "%I0.10": 0},                                  # -> HOME_SET
    {},                                                         # -> HOME_RETRACT
    AXES_AT_REST,                                               # -> READY, homed
    {"%I0.16": 0},                                              # E-stop: FAULT
    {"%I0.16": 1, "%MW106": 2, "%MW107": 7, "%MW108": 1},       # a move offered in FAULT
    {"%M102": 1},                                               # RESET: READY (homed)
    {},                                                         # READY: nothing to run
]
NEVER_RUNS = "never %M45 AND %M51"  # cutting_table.req.toml
REFUSAL = """LD    %X9
AND   [ %MW108 = 1 ]
[ %MW108 := -1 ]
"""


def test_cutting_table_fault_offer_never_runs():
    """An offer written during a fault is refused (INICIO := -1) and nothing runs after
    the RESET: the requirement holds on the whole run."""
    with PLC.from_file(LP / "cutting_table.il", LP / "cutting_table.toml",
                       devices=False) as plc:
        assert first_failure(plc, NEVER_RUNS, FAULT_OFFER) is None
        assert plc["%X4"] == 1 and plc["%MW108"] == -1 and plc["%MW128"] == 0


def test_cutting_table_requirement_catches_a_queued_fault_offer():
    """Without the refusal rung the offer stands through the fault and runs in the scan
    after the RESET (MOVING's first scan takes it): the requirement's tags see it, so
    `never %M45 AND %M51` is no vacuous proof."""
    text = (LP / "cutting_table.il").read_text()
    assert REFUSAL in text
    with PLC.from_source(text.replace(REFUSAL, ""), LP / "cutting_table.toml",
                         file="cutting_table_no_refusal.il", devices=False) as plc:
        assert first_failure(plc, NEVER_RUNS, FAULT_OFFER) == len(FAULT_OFFER)
        assert plc["%X5"] == 1 and plc["%MW148"] == 7  # segment 7 taken
