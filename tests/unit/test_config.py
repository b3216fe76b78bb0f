"""Configuration mistakes are clear errors, never silent defaults."""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.cli import main as softplc
from softplc.errors import ConfigError

PROG = "LD %I0.0\nIN %TM0\nLD %TM0.Q\nST %Q0.0\n"
TM0 = {"type": "TON", "base": "10ms", "preset": 3}


@pytest.mark.parametrize("config, message", [
    ({"timers": {"%TM0": {"type": "TON", "base": "10ms", "prest": 3}}},
     'timers."%TM0".prest: unknown key; known: base, preset, type'),
    ({"timers": {"%TM0": {"type": "TOX", "base": "10ms"}}}, "expected 'TON', 'TOF' or 'TP'"),
    ({"timers": {"%TM0": {"type": "TON", "base": "20ms"}}}, "1ms, 10ms, 100ms, 1s, 1min"),
    ({"timers": {"%TM0": {"type": "TON", "preset": 10000}}}, "less than or equal to 9999"),
    ({"timers": {"%C0": TM0}}, 'timers."%C0": \'%C0\' is not a %TM object'),
    ({"timers": {"%TM0": TM0}, "counters": {"%C0": {"preset": 5, "up": 1}}},
     "counters.\"%C0\".up: unknown key"),
    ({"timers": {"%TM0": TM0}, "scan_period": "fast"}, "not a duration"),
    ({"timers": {"%TM0": TM0}, "scan_periode": "10ms"},
     "scan_periode: unknown key; known: analog, constants"),
    ({"timers": {"%TM0": TM0}, "constants": {"%MW0": 3}}, "not a %KW/%KD/%KF constant"),
    ({"timers": {"%TM0": TM0}, "modules": {"9": "TM2DDO8TT"}}, "modules.9: slot 9 outside 1..7"),
    ({"timers": {"%TM0": TM0}, "modules": {"1": "TM2XYZ"}}, "unknown module"),
    ({"timers": {"%TM0": TM0}, "devices": {"X": {"type": "servo"}}},
     "devices.X.type: unknown device type 'servo'"),
    ({"timers": {"%TM0": TM0}, "profile": "TWDLCAE99"}, "unknown profile"),
])
def test_config_mistakes_are_named(config, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source(PROG, config)
    assert message in str(e.value)


def test_a_device_type_is_looked_up_only_when_a_device_section_names_it(monkeypatch):
    """`assembly.load` looks a device type up (which imports its module: numpy for a servo
    axis, a machine's package) only for the types a [devices] section names; the unknown
    type's message lists the catalog's names without importing any. Which modules a fresh
    process imports: tests/e2e/test_device_imports.py."""
    from softplc.assembly import load
    from softplc.devices.base import DeviceTypes

    found = []
    lookup = DeviceTypes.__getitem__

    def counted(self, name):
        cls = lookup(self, name)
        found.append(name)
        return cls

    monkeypatch.setattr(DeviceTypes, "__getitem__", counted)
    assert load({"scan_period": "10ms", "timers": {"%TM0": TM0}}).settings.devices == {}
    assert PLC.from_source(PROG, {"timers": {"%TM0": TM0}}) is not None
    assert found == []
    with pytest.raises(ConfigError, match=r"devices\.X\.type: unknown device type 'nope'; "
                       r"known: .*stepper"):
        load({"devices": {"X": {"type": "nope"}}})
    assert found == []
    coils = ["%Q0.0", "%Q0.1", "%Q0.2", "%Q0.3"]
    loaded = load({"devices": {"X": {"type": "stepper", "phases": coils}}})
    assert loaded.settings.devices["X"].options.phases == coils
    assert found == ["stepper"]


def test_toml_syntax_error_names_the_file(tmp_path):
    cfg = tmp_path / "m.toml"
    cfg.write_text('scan_period = "10ms\n')
    with pytest.raises(ConfigError, match="m.toml"):
        PLC.from_source(PROG, cfg)


def test_daemon_rejects_an_unknown_modbus_key(tmp_path, capsys):
    prog = tmp_path / "p.il"
    prog.write_text("LD 1\nST %M0\n")
    cfg = tmp_path / "m.toml"
    cfg.write_text("[modbus]\nprot = 5021\n")
    assert softplc(["run", str(prog), "--config", str(cfg), "--port", "0"]) == 1
    err = capsys.readouterr().err
    assert "modbus.prot: unknown key" in err and "Traceback" not in err
