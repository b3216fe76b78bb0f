"""The README's examples run as written (so the README cannot drift from the code)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from softplc import PLC

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()

pytest_plugins = ["pytester"]


def block(after: str, lang: str) -> str:
    """The first ```lang block after the heading or sentence `after`."""
    start = README.index(after)
    m = re.compile(rf"```{lang}\n(.*?)```", re.S).search(README, start)
    assert m, f"no {lang} block after {after!r}"
    return m.group(1)


def test_python_api_example(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    exec(compile(block("## Python API", "python"), "README.md", "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == "0.61 61 RUN"  # as the comment in the README says
    x, z, pen = printed[1].split()
    assert (int(float(x)), int(float(z)), pen) == (1000, 500, "True")


def test_configuration_example_loads():
    cfg = tomllib.loads(block("## Configuration", "toml"))
    plc = PLC.from_source("LD %I0.0\nIN %TM0\nLD %TM0.Q\nCU %C0\nLD %C0.D\nU %DR0\n"
                          "LD 1\n[ %MF4 := %KF2 * 2.0 ]\nI %R0\n", cfg)
    plc.scan(3)
    assert plc["%MF4"] == 3.0 and "X" in plc.devices


def test_pytest_plugin_example(pytester):
    pytester.makepyfile(test_user=block("Installing softplc registers a pytest plugin", "python"))
    for sub in ("ladder_programs",):
        dst = pytester.path / sub
        dst.mkdir()
        for f in (ROOT / sub).glob("drawing_table.*"):
            (dst / f.name).write_text(f.read_text())
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=2)


@pytest.mark.parametrize("cmd", re.findall(r"^softplc (\w+) ", README, re.M))
def test_every_command_in_the_readme_exists(cmd):
    from softplc.cli import COMMAND_MODULES

    assert cmd in COMMAND_MODULES


def test_servo_parameter_table_is_the_code_s():
    from softplc.devices.axis.law import markdown_table

    assert markdown_table() in README
