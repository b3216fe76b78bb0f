"""One typed configuration (issue 22 item 2): every section checked by the schema, every
problem collected with its code and key path, and the machine builder's typed record."""

from __future__ import annotations

import json
from datetime import datetime

import pytest

from softplc import PLC
from softplc.assembly import Machine
from softplc.cli import main as softplc
from softplc.config import Config, read_toml, validate_config
from softplc.config.models import ExchConfig, RtcConfig, ScheduleConfig
from softplc.errors import ConfigCode, ConfigError
from softplc.runtime.exch import ExchPort

PROG = "LD 1\nST %M0\n"


def issues(config: dict) -> dict[str, ConfigCode]:
    """Key path -> code of every problem `config` has (building a PLC on it)."""
    with pytest.raises(ConfigError) as e:
        PLC.from_source(PROG, config)
    return {i.path: i.code for i in e.value.issues}


def test_sections_are_typed_models():
    cfg = validate_config({
        "modules": {1: "twdami2ht"}, "analog": {"%IW1.0": {"type": "0-10V"}},
        "rtc": {"start": datetime(2026, 1, 1)}, "exch": {"remote": {"2": {"host": "h"}}},
        "schedule": {"3": {"output": "%Q0.0", "start": "07:00", "stop": "08:00"}},
        "symbols": {"GO": "%I0.0", "STOP": {"address": "%I0.1", "comment": "red"}}})
    assert cfg.modules == {1: "TWDAMI2HT"}  # numbered key read as a number, name checked
    assert isinstance(cfg.rtc, RtcConfig) and isinstance(cfg.exch, ExchConfig)
    assert list(cfg.exch.remote) == [2] and isinstance(cfg.schedule[3], ScheduleConfig)
    assert cfg.symbols["STOP"].comment == "red"
    # every section is a typed model, not a raw table (the block sections are issue 22's
    # catalog's: h-catalog types them)
    raw = {name for name, f in Config.model_fields.items() if "Any" in str(f.annotation)}
    assert raw <= {"pid", "pls", "pwm", "fast_counters", "very_fast_counters"}


def test_every_problem_is_reported_at_once_with_code_and_path():
    found = issues({
        "scan_periode": "10ms",                                   # schema: unknown key
        "modules": {"9": "TM2DDO8TT", "2": "NOPE"},               # slot, module name
        "exch": {"remote": {"17": {"host": "h"}}},                # numbered key range
        "schedule": {"16": {"output": "%Q0.0", "start": "7", "stop": "08:00"}},
        "daemon": {"host_wait": "%MW3"},
        "modbus": {"allow": ["10.0.0.1", "nonsense"]},
    })
    assert found == {
        "scan_periode": ConfigCode.UNKNOWN_KEY,
        "modules.9": ConfigCode.VALUE,
        "modules.2": ConfigCode.VALUE,
        "exch.remote.17": ConfigCode.VALUE,
        "schedule.16": ConfigCode.VALUE,
        "schedule.16.start": ConfigCode.VALUE,
        "daemon.host_wait": ConfigCode.VALUE,
        "modbus.allow[1]": ConfigCode.VALUE,
    }


def test_build_time_problems_are_collected_too():
    """What needs the profile and the memory image (addresses, channels) is checked by the
    builder, which also reports them all."""
    found = issues({
        "constants": {"%MW0": 3, "%KW0": 70000, "%KW99999": 1},
        "analog": {"%IW4.0": {"type": "0-10V"}, "%IW0.0": {"type": "PT100"}},
        "schedule": {"0": {"output": "%MW0", "start": "07:00", "stop": "08:00"}},
    })
    assert found == {
        'constants."%MW0"': ConfigCode.ADDRESS,
        'constants."%KW0"': ConfigCode.VALUE,
        'constants."%KW99999"': ConfigCode.ADDRESS,
        'analog."%IW4.0"': ConfigCode.MODULE,
        'analog."%IW0.0".type': ConfigCode.VALUE,
        "schedule.0.output": ConfigCode.ADDRESS,
    }


def test_a_file_names_itself_once(tmp_path):
    f = tmp_path / "m.toml"
    f.write_text('scan_period = 10\n[timers."%TM0"]\nprset = 1\n')
    with pytest.raises(ConfigError) as e:
        PLC.from_source(PROG, f)
    assert e.value.file == str(f) and len(e.value.issues) == 2
    assert str(e.value).startswith(f"{f}:\n  ") and str(e.value).count(str(f)) == 1
    f.write_text("x = [\n")
    with pytest.raises(ConfigError) as e:
        read_toml(f)
    assert e.value.issues[0].code == ConfigCode.FILE and "not valid TOML" in str(e.value)


def test_check_json_gives_each_issue_its_code(tmp_path, capsys):
    prog, cfg = tmp_path / "p.il", tmp_path / "m.toml"
    prog.write_text(PROG)
    cfg.write_text('[modules]\n9 = "TM2DDO8TT"\n[rtc]\nbegin = 1\n')
    assert softplc(["check", str(prog), "--config", str(cfg), "--json"]) == 1
    errors = json.loads(capsys.readouterr().out)["errors"]
    assert {(e["text"], e["code"]) for e in errors} == {
        ("modules.9", "value"), ("rtc.begin", "unknown-key")}
    assert all(e["file"] == str(cfg) for e in errors)


def test_the_builder_returns_the_parts_the_facade_shows():
    plc = PLC.from_source("LD %I0.0\nST %Q0.0\n", {"exch": {"remote": {"1": {"host": "h"}}}})
    m = plc.machine
    assert isinstance(m, Machine) and isinstance(m.exch, ExchPort)
    assert (plc.mem, plc.engine, plc.settings, plc.profile) == \
        (m.mem, m.engine, m.settings, m.profile)
    plc["%I0.0"] = 1
    plc.scan()
    assert plc["%Q0.0"] == 1 and plc.scan_count == 1 and plc.state == "RUN"
    plc.stop()
    assert plc.state == "STOP"
    plc.close()


def test_numbered_keys_follow_the_profile():
    """exch.remote's indexes are 1 .. the profile's count; modules' slots 1 .. its slots."""
    with pytest.raises(ConfigError, match="exch.remote.0: the remote device index is 1 .. "):
        validate_config({"exch": {"remote": {"0": {"host": "h"}}}})
    with pytest.raises(ConfigError, match=r"modules.x: slot x outside 1..7"):
        validate_config({"modules": {"x": "TM2DDO8TT"}})


def test_machine_files_of_other_commands_go_through_the_loader(tmp_path):
    """`softplc cut --machine` reads the axes' start and scale from the checked devices; the
    servo rig names a missing axis; a misspelt option is a key path, not a KeyError."""
    from softplc.devices.axis.rig import load_axes
    from softplc.machines.cutting.geometry import CuttingError
    from softplc.machines.cutting.run import _machine_axes

    assert _machine_axes("ladder_programs/cutting_table.toml") == \
        ((12340000.0, 5700000.0), 100000.0)
    bad = tmp_path / "m.toml"
    bad.write_text('[devices.X]\ntype = "servo_axis"\ncounts_per_mn = 1.0\n')
    with pytest.raises(CuttingError, match=r"m.toml:\n  devices.X.plant: required key missing"
                       r"\n  devices.X.counts_per_mn: unknown key"):
        _machine_axes(str(bad))
    with pytest.raises(ConfigError, match=r"no \[devices.Z\]; devices: X"):
        load_axes(bad, "Z")
