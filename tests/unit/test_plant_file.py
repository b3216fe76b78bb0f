"""The plant file (issue 35): its schema, every problem with its line and code, and the
shared conveyor's physics."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.errors import ConfigError
from softplc.plant.model import PlantError, line_of, load_plant
from softplc.plant.physics import Conveyor

PROGRAM = "LD 1\nST %Q0.0\n"
GOOD = """\
name = "t"

[controllers.m]
program = "p.il"

[controllers.a]
program = "p.il"
address = 1

[links.line]
master = "m"
peers = ["a"]

[devices.belt]
type = "conveyor"
length = 2.0
speed = 1.0
stations = { s = 1.0 }

[[wires]]
from = "m:%Q0.0"
to = "belt:run"

[[wires]]
from = "belt:at_s"
to = ["a:%I0.0", "m:%I0.1"]
"""


def write(tmp_path: Path, text: str) -> Path:
    (tmp_path / "p.il").write_text(PROGRAM)
    f = tmp_path / "plant.toml"
    f.write_text(text)
    return f


def test_a_good_plant_file_gives_each_linked_controller_its_link_section(tmp_path):
    spec = load_plant(write(tmp_path, GOOD))
    assert spec.configs["m"].settings.remote_link.remotes == {1: "peer"}
    assert spec.configs["a"].settings.remote_link.address == 1
    (_, src, targets), = [w for w in spec.wires if w[1].device]
    assert (src.owner, src.what, [t.what for t in targets]) == ("belt", "at_s",
                                                                 ["%I0.0", "%I0.1"])


@pytest.mark.parametrize(("old", "new", "line", "message", "code"), [
    ('program = "p.il"\n\n[controllers.a]', 'program = "p.il"\nspeed = 3\n\n[controllers.a]',
     5, "controllers.m.speed: unknown key", "unknown-key"),
    ('peers = ["a"]', 'peers = ["b"]', 12, "'b' is not a controller", "missing-key"),
    ('to = "belt:run"', 'to = "belt:motor"', 22, "belt has input signals run, hold_s",
     "address"),
    ('from = "m:%Q0.0"', 'from = "m:%I0.0"', 21, "from an output %Q to an input %I",
     "address"),
    ('to = ["a:%I0.0", "m:%I0.1"]', 'to = ["a:%I0.0", "a:%I0.0"]', 26,
     "is already driven by wire 1", "conflict"),
    ("stations = { s = 1.0 }", "stations = { s = 3.0 }", 18, "s at 3.0 m is off the belt",
     "value"),
    ('type = "conveyor"', 'type = "mixer"', 15, "unknown shared device type 'mixer'",
     "device"),
    ("address = 1", "address = 0", 8, "needs a Remote Link address", "missing-key"),
    ('program = "p.il"\naddress', 'program = "q.il"\naddress', 7, "no such file", "file"),
])
def test_plant_file_errors_have_their_line_and_code(tmp_path, old, new, line, message, code):
    assert old in GOOD
    f = write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(PlantError) as e:
        load_plant(f)
    issue = next(i for i in e.value.plant_issues if message in str(i))
    assert (issue.line, str(issue.code)) == (line, code)
    assert str(issue).startswith(f"{f}:{line}: ")


def test_every_problem_is_reported_at_once(tmp_path):
    f = write(tmp_path, GOOD.replace('peers = ["a"]', 'peers = ["b"]').replace(
        'to = "belt:run"', 'to = "belt:motor"'))
    with pytest.raises(PlantError) as e:
        load_plant(f)
    assert len(e.value.plant_issues) == 2


def test_a_controllers_own_configuration_error_names_its_file(tmp_path):
    (tmp_path / "c.toml").write_text('scan_period = "fast"\n')
    f = write(tmp_path, GOOD.replace('[controllers.a]\nprogram = "p.il"',
                                     '[controllers.a]\nprogram = "p.il"\nconfig = "c.toml"'))
    with pytest.raises(ConfigError, match=r"c\.toml:\n  scan_period: not a duration"):
        load_plant(f)


def test_a_link_section_contradicting_the_plant_is_refused(tmp_path):
    (tmp_path / "c.toml").write_text("[remote_link]\naddress = 3\n")
    f = write(tmp_path, GOOD.replace('[controllers.a]\nprogram = "p.il"',
                                     '[controllers.a]\nprogram = "p.il"\nconfig = "c.toml"'))
    with pytest.raises(PlantError, match="address 1 but its configuration's"):
        load_plant(f)


def test_line_of_finds_tables_arrays_and_dotted_keys():
    text = GOOD + '\n[controllers.z]\nprogram = "p.il"\nhost.x = 1\n'
    assert line_of(text, ("controllers", "a", "address")) == 8
    assert line_of(text, ("wires", 1, "to")) == 26
    assert line_of(text, ("controllers", "z", "host", "x")) == 30
    assert line_of(text, ("nothing",)) == 1


# ---- the conveyor ----------------------------------------------------------------------------
def belt(**kw) -> Conveyor:
    opts = {"length": 2.0, "speed": 1.0, "box": 0.2, "gap": 0.1, "feed_every": "10s",
            "stations": {"s": 1.0}, "sensors": {"end": 1.9}} | kw
    return Conveyor("belt", Conveyor.Options.model_validate(opts))


def run(b: Conveyor, seconds: float, dt: float = 0.01, t0: float = 0.0) -> float:
    t = t0
    for _ in range(round(seconds / dt)):
        t += dt
        b.update(t, dt)
    return t


def test_a_box_rides_the_belt_to_the_end():
    b = belt()
    b.inputs["run"] = True
    t = run(b, 1.0)  # fed at t = 0.01 with its front at 0.2: now at 1.19
    assert b.fed == 1 and b.outputs["at_s"] and not b.outputs["end"]
    run(b, 2.0, t0=t)
    assert b.delivered == 1 and b.boxes == ()


def test_a_raised_gate_holds_boxes_which_queue_apart():
    b = belt(feed_every="350ms")
    b.inputs.update(run=True, hold_s=True)
    run(b, 3.0)
    fronts = b.boxes
    assert fronts[0] == 1.0 and b.outputs["at_s"]
    assert all(a - f >= 0.2 + 0.1 - 1e-9 for a, f in zip(fronts, fronts[1:], strict=False))
    b.inputs["hold_s"] = False
    run(b, 0.25, t0=3.0)
    assert b.boxes[0] > 1.0 and not b.outputs["at_s"]  # a gap passes under the eye


def test_the_belt_stands_still_without_run():
    b = belt()
    b.inputs["run"] = True
    run(b, 0.5)
    before = b.boxes
    b.inputs["run"] = False
    run(b, 1.0, t0=0.5)
    assert b.boxes == before
