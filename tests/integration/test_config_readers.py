"""Issue 22: the configuration is read through the typed `Config` only (`plc.settings`),
and every problem, the devices' included, is collected with its code and key path."""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.errors import ConfigCode, ConfigError
from softplc.modbus import tags
from softplc.modbus.regmap import COILS, REGISTERS

PROG = "LD 1\nST %M0\n"


def issues(config: dict, program: str = PROG) -> dict[str, tuple[ConfigCode, str]]:
    """Key path -> (code, message) of every problem `config` has (building a PLC on it)."""
    with pytest.raises(ConfigError) as e:
        PLC.from_source(program, config)
    return {i.path: (i.code, i.message) for i in e.value.issues}


def test_read_only_ranges_are_typed_and_every_wrong_entry_reported():
    found = issues({"modbus": {"read_only": ["%MW100:10", "%Q0.0", "%MW99999", "%MW3:X2",
                                             "junk", 5]},
                    "scan_period": "1"})
    assert {p: c for p, (c, _) in found.items()} == {
        "modbus.read_only[1]": ConfigCode.ADDRESS,
        "modbus.read_only[2]": ConfigCode.ADDRESS,
        "modbus.read_only[3]": ConfigCode.ADDRESS,
        "modbus.read_only[4]": ConfigCode.ADDRESS,
        "modbus.read_only[5]": ConfigCode.TYPE,
        "scan_period": ConfigCode.VALUE,
    }
    assert "only %M, %MW, %MD, %MF" in found["modbus.read_only[1]"][1]
    assert "beyond the controller profile" in found["modbus.read_only[2]"][1]
    # one entry may be written as a string; it is checked the same way
    assert list(issues({"modbus": {"read_only": "%I0.0"}})) == ["modbus.read_only[0]"]


def test_the_map_reads_the_typed_ranges():
    plc = PLC.from_source("LD %M9\nST %M0\n[ %MW101 := %MD40 ]\n",
                          {"modbus": {"read_only": ["%MW100:10", "%MD40", "%M8:4"]}})
    assert plc.settings.modbus.read_only == ["%MW100:10", "%MD40", "%M8:4"]
    ro, devices = tags.host_read_only(plc)
    assert ro.registers == ((100, 110), (40, 42)) and ro.coils == ((8, 12),)
    assert devices == {}
    access = {t.address: (t.space, t.access) for t in tags.of_plc(plc).tags}
    assert access == {"%M0": (COILS, "read/write"), "%M9": (COILS, "read"),
                      "%MW101": (REGISTERS, "read"), "%MD40": (REGISTERS, "read")}
    plc.close()


def test_the_io_layout_reads_the_typed_modules():
    from softplc.access.machine import MachineInfo

    # a Python dict may give slots as numbers and names in any case: the schema settles it
    plc = PLC.from_source("LD %I1.0\nST %Q2.1\n",
                          {"modules": {2: "tm2ddo8tt", "1": "TM2DDI8DT", 3: "TWDAMM3HT"}})
    assert [(m["slot"], m["name"], m["inputs"], m["outputs"])
            for m in MachineInfo(plc).io_layout()] == [
        (0, "TWDLCAE40DRF", 24, 16), (1, "TM2DDI8DT", 8, 0), (2, "TM2DDO8TT", 0, 8),
        (3, "TWDAMM3HT", 0, 0)]
    plc.close()


DRUM_PROG = "LD %I0.0\nU %DR0\nLD %I0.1\nR %DR0\n"


def drum_config(outputs: list[str]) -> dict:
    return {"symbols": {"LAMP_A": "%Q0.0", "LAMP_C": {"address": "%Q0.2"}},
            "drums": {"%DR0": {"steps": [1, 2, 4, 2], "outputs": outputs}}}


def test_a_drum_output_given_as_a_symbol_runs_and_is_verified():
    from softplc.verify.checker import Checker
    from softplc.verify.engines import verify
    from softplc.verify.model import Model
    from softplc.verify.requirements import load_spec

    def status(check: str) -> str:
        plc = PLC.from_source(DRUM_PROG, cfg, devices=False)
        spec = load_spec(None, [check], plc.profile)
        model = Model(plc, spec.reads, spec.host)
        return verify(Checker(model, spec, spec.requirements[0]), 8, 4, 20, [],
                      use_spacer=True).status

    cfg = drum_config(["LAMP_A", "%Q0.1", "lamp_c"])
    plc = PLC.from_source(DRUM_PROG, cfg)
    plc.scan()
    assert (plc["%Q0.0"], plc["%Q0.1"], plc["%Q0.2"]) == (1, 0, 0)
    plc["%I0.0"] = 1
    plc.scan(2)
    assert (plc["%Q0.0"], plc["%Q0.1"], plc["%Q0.2"]) == (0, 1, 0)
    plc.close()
    # the verifier models the drum's outputs from the same typed, resolved configuration
    assert status("never %Q0.0 AND %Q0.2") == "PROVEN"
    assert status("never %Q0.2") == "VIOLATED"  # the third step, on LAMP_C


def test_wrong_drum_outputs_are_all_reported():
    found = issues(drum_config(["LAMP_B", "%MW3", "LAMP_C"]),
                   "LD %I0.0\nU %DR0\n")
    assert {p: c for p, (c, _) in found.items()} == {
        'drums."%DR0".outputs[0]': ConfigCode.ADDRESS,
        'drums."%DR0".outputs[1]': ConfigCode.ADDRESS}
    assert "unknown symbol 'LAMP_B'" in found['drums."%DR0".outputs[0]'][1]


BAD_DEVICES = {
    "constants": {"%MW0": 3},                                    # the builder's
    "devices": {
        "start": {"type": "push_button", "input": "%Q0.0"},      # not an input
        "stop": {"type": "push_button", "input": "%I0.99"},      # beyond the base
        "home": {"type": "limit_switch", "axis": "start", "input": "%I0.2"},  # not an axis
    },
}
PHASES = ["%Q0.4", "%Q0.5", "%Q0.6", "%Q0.7"]


def test_device_problems_are_collected_with_the_builders():
    found = issues(BAD_DEVICES)
    assert {p: c for p, (c, _) in found.items()} == {
        'constants."%MW0"': ConfigCode.ADDRESS,
        "devices.start.input": ConfigCode.ADDRESS,
        "devices.stop.input": ConfigCode.ADDRESS,
        "devices.home.axis": ConfigCode.DEVICE,
    }
    # what the devices' options models see is the schema's, reported with the rest of it
    found = issues({"scan_period": "1",
                    "devices": {"feed": {"type": "analog_source", "input": "%IW0.0",
                                         "profile": [[0, 1], [2, 3], [1, 5]]},
                                "oven": {"type": "oven", "sensor": "%IW0.0"}}})
    assert {p: c for p, (c, _) in found.items()} == {
        "scan_period": ConfigCode.VALUE, "devices.feed.profile": ConfigCode.VALUE,
        "devices.oven": ConfigCode.VALUE}
    assert "times must increase (1 s after 2 s)" in found["devices.feed.profile"][1]
    # devices that cannot be made: each reported; the others are not bound (they may name
    # one of them: this switch's axis)
    found = issues({"devices": {
        "x": {"type": "stepper", "phases": PHASES, "travel": 10.0, "start": 20.0},
        "y": {"type": "stepper", "phases": PHASES, "travel": 10.0, "start": -5.0},
        "home": {"type": "limit_switch", "axis": "x", "input": "%I0.2"}}})
    assert {p: c for p, (c, _) in found.items()} == {
        "devices.x.start": ConfigCode.VALUE, "devices.y.start": ConfigCode.VALUE}


def test_check_json_shows_each_device_problem(tmp_path, capsys):
    import json

    from softplc.cli import main as softplc

    prog, cfg = tmp_path / "p.il", tmp_path / "m.toml"
    prog.write_text(PROG)
    cfg.write_text('[devices.start]\ntype = "push_button"\ninput = "%Q0.0"\n'
                   '[devices.stop]\ntype = "push_button"\ninput = "%I0.99"\n')
    assert softplc(["check", str(prog), "--config", str(cfg), "--json"]) == 1
    errors = json.loads(capsys.readouterr().out)["errors"]
    assert {(e["text"], e["code"]) for e in errors} == {
        ("devices.start.input", "address"), ("devices.stop.input", "address")}
    assert all(e["file"] == str(cfg) for e in errors)


def test_the_parser_gets_the_typed_symbols_of_a_checked_configuration(tmp_path):
    # every wrong declaration at its key path, with its code: the schema's, then the table's
    found = issues({"symbols": {"GO": "%I0.0", "Y": 5,
                                "Z": {"address": "%M0", "colour": "red"}}})
    assert {p: c for p, (c, _) in found.items()} == {
        "symbols.Y": ConfigCode.VALUE, "symbols.Z.colour": ConfigCode.UNKNOWN_KEY}
    found = issues({"symbols": {"GO": "%I0.0", "go": "%I0.1", "LD": "%I0.2", "X": "%MW0:4"}})
    assert {p: c for p, (c, _) in found.items()} == {
        "symbols.go": ConfigCode.CONFLICT, "symbols.LD": ConfigCode.VALUE,
        "symbols.X": ConfigCode.ADDRESS}
    # the configuration is checked before the program is parsed: its problems come first,
    # named in the file, not a cascade of unknown names in the program
    cfg = tmp_path / "m.toml"
    cfg.write_text('scan_period = "1"\n[symbols]\nGO = "%I0.0"\n')
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD GO\nST MOTOR\n", cfg)
    assert e.value.file == str(cfg) and [i.path for i in e.value.issues] == ["scan_period"]
    cfg.write_text('[symbols]\nGO = "%I0.0"\nMOTOR = { address = "%Q0.0", comment = "K1" }\n')
    plc = PLC.from_source("LD GO\nST MOTOR\n", cfg)
    plc["GO"] = 1
    plc.scan()
    assert plc["%Q0.0"] == 1 and plc.symbols.comment_of(plc.symbols.ref("MOTOR")) == "K1"
    plc.close()


def test_the_application_id_is_the_raw_tables_in_one_place():
    """`softplc run` and an online change name the application the same way (the state
    file's owner): the program and the configuration as written, less the daemon's."""
    from softplc.access.program import ProgramAccess
    from softplc.assembly import application_id
    from softplc.persist import retain

    cfg = {"timers": {"%TM0": {"preset": 5}}, "modbus": {"port": 1502}}
    plc = PLC.from_source(PROG, cfg)
    app = application_id(plc.machine, PROG.encode())
    assert app == retain.application_id(PROG.encode(), cfg)
    assert app == ProgramAccess(plc, None).app_id(PROG, None)
    moved = PLC.from_source(PROG, {**cfg, "modbus": {"port": 1503}})
    assert application_id(moved.machine, PROG.encode()) == app
    plc.close()
    moved.close()


def test_block_set_up_problems_are_all_reported():
    found = issues({"timers": {"%TM0": {"preset": 5}, "%TM999": {}, "%C0": {}},
                    "counters": {"%Q0.0": {}},
                    "drums": {"%DR0": {"outputs": ["%MW0"]}},
                    "pls": {"%PLS7": {"base": "10ms", "preset": 10}},
                    "modbus": {"read_only": "%MW0"}})
    assert {p: c for p, (c, _) in found.items()} == {
        'timers."%TM999"': ConfigCode.ADDRESS, 'timers."%C0"': ConfigCode.ADDRESS,
        'counters."%Q0.0"': ConfigCode.ADDRESS, 'drums."%DR0".outputs[0]': ConfigCode.ADDRESS,
        'pls."%PLS7"': ConfigCode.ADDRESS}


def test_an_online_change_resolves_drum_outputs_with_its_own_symbols():
    from softplc.online import apply, plan

    plc = PLC.from_source(DRUM_PROG, drum_config(["LAMP_A"]))
    plc.scan()
    assert plc["%Q0.0"] == 1
    new = drum_config(["LAMP_A"])
    new["symbols"]["LAMP_A"] = "%Q0.3"  # the same name, another output
    change = plan(plc, DRUM_PROG, new)
    apply(plc, change, confirm=True)
    plc["%Q0.0"] = 0
    plc.scan()
    assert (plc["%Q0.0"], plc["%Q0.3"]) == (0, 1)
    assert str(plc.symbols.ref("LAMP_A")) == "%Q0.3"
    plc.close()


def test_the_machining_centre_reads_its_machine_through_the_loader(tmp_path):
    from pathlib import Path

    from softplc.machines.machining.centre import MACHINE_TOML, MachiningCentre, machine_devices

    typed, tables = machine_devices()
    assert typed["scope"].options.torque_per_bit == 0.01 and typed["X"].options.plant.K > 0
    assert tables["scope"]["axis"] == "X"  # the tables as written, for the rig's overrides
    text = Path(MACHINE_TOML).read_text(encoding="utf-8")
    bad = tmp_path / "m.toml"
    bad.write_text(text.replace("torque_per_bit = 0.01", "torque_per_bit = -1.0")
                   .replace('axis = "X"', 'axis = "Y"', 1), encoding="utf-8")
    with pytest.raises(ConfigError) as e:  # every wrong key, not a KeyError
        MachiningCentre(tmp_path, 1000.0, config=bad)
    assert [i.path for i in e.value.issues] == ["devices.scope.torque_per_bit"]
    bad.write_text(text.replace('axis = "X"', 'axis = "Y"', 1), encoding="utf-8")
    with pytest.raises(ConfigError, match="expected a scope device named scope and the "
                                          "servo_axis its `axis` names"):
        MachiningCentre(tmp_path, 1000.0, config=bad)


def test_every_device_option_model_is_strict():
    """A string is not a number in any device's options (the scope's and the drive
    tuning's models were plain pydantic models that turned "0.01" into 0.01)."""
    from pydantic import ValidationError

    from softplc.machines.machining.drive_tuning import DriveTuningOptions
    from softplc.machines.machining.scope import ScopeOptions

    with pytest.raises(ValidationError, match="valid number"):
        ScopeOptions(axis="X", torque_per_bit="0.01")
    with pytest.raises(ValidationError):
        ScopeOptions(axis="X", torque_per_bit=0.01, noise=[0, 0, 0])  # four sds
    with pytest.raises(ValidationError, match="valid string"):
        DriveTuningOptions(axis=1)
    assert ScopeOptions(axis="X", torque_per_bit=1).noise == [0.0] * 4
