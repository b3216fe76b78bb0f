"""Mutated machine configurations: a config either loads (and the PLC with its devices then
scans) or is refused with a ConfigError naming the key path. Never another exception.

The seeds are the configs of ladder_programs/*.toml with their programs; hypothesis swaps a
value for another type or an out-of-range value (as a TOML file can hold: strings, ints,
floats including inf and nan, bools, lists, tables), deletes a key or adds an unknown one.
"""

from __future__ import annotations

import copy
import math
import tomllib
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from doc_paths import at, key_paths
from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softplc import PLC
from softplc.errors import ConfigError, ProgramError
from softplc.il.parser import parse_file
from softplc.modbus.regmap import read_only_of

ROOT = Path(__file__).resolve().parents[2]
# machine configurations (a `.req.toml` beside a program holds its requirements: verify)
SEEDS = sorted(p for p in (ROOT / "ladder_programs").glob("*.toml")
               if not p.name.endswith(".req.toml"))

scalars = st.one_of(
    st.integers(-2**40, 2**40), st.sampled_from([0, -1, 1, 9999, 10000, 65536, 2**63]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.inf, -math.inf, math.nan, 1e308, -0.0, 0.5]),
    st.booleans(),
    st.sampled_from(["", "10", "10ms", "0ms", "-5ms", "1e400s", "inf", "nanms", "1min",
                     "TON", "FIFO", "%Q0.0", "%I0.0", "%TM0", "%KW0", "%MW0:4", "X", "pen",
                     "home", "end", "stuck_open", "TM2DDO8TT", "1ms", "100ms", "2s"]),
    st.text(max_size=8),
)
values = st.one_of(
    scalars,
    st.lists(scalars, max_size=5),
    st.dictionaries(st.sampled_from(["type", "preset", "base", "x", "%TM9"]), scalars,
                    max_size=3),
)


@cache
def _seed(path: Path) -> tuple[dict[str, Any], Any, list[tuple[Any, ...]]]:
    cfg = tomllib.loads(path.read_text(encoding="utf-8"))
    if "symbols_file" in cfg:  # a dict config has no folder: the file's path made whole
        cfg["symbols_file"] = str(path.parent / cfg["symbols_file"])
    # the daemon's sections too, so that their values get mutated as well
    cfg.setdefault("modbus", {"port": 5020, "read_only": ["%MW100:4"], "frame_timeout": "2s"})
    cfg.setdefault("daemon", {"save_interval": "5s", "rt_priority": 10})
    tables = [()] + [p for p in key_paths(cfg) if isinstance(at(cfg, p), dict)]
    return cfg, parse_file(path.with_suffix(".il")), key_paths(cfg) + [("+",) + t for t in tables]


@st.composite
def mutated(draw: st.DrawFn) -> tuple[Path, dict[str, Any], Any]:
    path = draw(st.sampled_from(SEEDS))
    cfg0, program, paths = _seed(path)
    cfg = copy.deepcopy(cfg0)
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(paths))
        try:
            if where[0] == "+":  # an unknown key in a table
                at(cfg, where[1:])[draw(st.sampled_from(["bogus", "Type", "presets"]))] = \
                    draw(values)
                continue
            parent = at(cfg, where[:-1])
            if draw(st.integers(0, 5)) == 0 and isinstance(parent, dict):
                del parent[where[-1]]
            else:
                parent[where[-1]] = draw(values)
        except (KeyError, IndexError, TypeError):
            pass  # an earlier mutation replaced or removed this path
    return path, cfg, program


@settings(max_examples=examples(150), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(case=mutated())
def test_mutated_config_loads_or_is_a_config_error(case):
    path, cfg, program = case
    try:
        plc = PLC(program, cfg)
    except ConfigError as e:
        text = str(e)
        assert text and "Traceback" not in text and ":" in text
        return
    except ProgramError as e:  # e.g. a timer the program uses was removed from the config
        assert e.diagnostics
        return
    try:
        plc.scan(5)  # the devices run too: a config that loads must not crash a scan
        # what the daemon reads at start-up: the read-only ranges the schema checked
        read_only_of(plc.settings.modbus.read_only, plc.profile)
    finally:
        plc.close()


@pytest.mark.parametrize("seed", SEEDS, ids=lambda p: p.name)
def test_seed_configs_load_and_scan(seed):
    cfg, program, _ = _seed(seed)
    plc = PLC(program, cfg)
    plc.scan(5)
    assert plc.state != "HALT"
    plc.close()


@pytest.mark.parametrize("mutation, message", [
    ({"scan_period": 10}, 'scan_period: a bare number is ambiguous: write the unit, e.g. "10ms"'),
    ({"scan_period": math.inf}, "scan_period: not a duration"),
    ({"watchdog": "1e400s"}, "watchdog: longer than 24 h"),
    ({"timers": ["%TM0"]}, "timers: expected a table (got ['%TM0'])"),
    ({"constants": {"%KW0": math.inf}}, 'constants."%KW0": expected a valid integer or a '
                                        'finite number (got inf)'),
    ({"modbus": {"port": "502"}}, "modbus.port: expected a valid integer (got '502')"),
    ({"daemon": {"save_interval": 5}}, "daemon.save_interval: a bare number is ambiguous"),
])
def test_mutation_messages_name_path_value_and_expectation(mutation, message):
    cfg, program, _ = _seed(ROOT / "ladder_programs" / "drawing_table.toml")
    with pytest.raises(ConfigError) as e:
        PLC(program, {**cfg, **mutation})
    assert message in str(e.value)


def test_every_problem_is_reported_at_once():
    cfg, program, _ = _seed(ROOT / "ladder_programs" / "drawing_table.toml")
    cfg = copy.deepcopy(cfg)
    cfg["scan_period"] = 1
    cfg["devices"]["X"]["travel"] = "25"
    cfg["devices"]["pen"]["colour"] = "red"
    with pytest.raises(ConfigError) as e:
        PLC(program, cfg)
    lines = str(e.value).splitlines()
    assert any(s.startswith("scan_period: a bare number") for s in lines)
    assert "devices.X.travel: expected a valid number (got '25')" in lines
    assert "devices.pen.colour: unknown key; known: lift_delay, lower_delay, output" in lines


def test_config_file_errors_name_the_file(tmp_path):
    bad = tmp_path / "m.toml"
    bad.write_text('scan_period = 10\n[timers."%TM0"]\nbase = "1ms"\npreset = "3"\n')
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD %TM0.Q\nST %Q0.0\n", bad)
    text = str(e.value)
    assert text.startswith(f"{bad}:")
    assert "scan_period: a bare number" in text and 'timers."%TM0".preset' in text
    with pytest.raises(ConfigError, match="nosuch.toml: no such file"):
        PLC.from_source("LD 1\nST %Q0.0\n", tmp_path / "nosuch.toml")
