"""The examples of the README and of the documentation site (docs/) run as written, so the
documentation cannot drift from the code: the first example of the README, the Python API,
the configuration and pytest pages, and every command line, TOML and Python block of every
page (each command and option exists, each TOML block parses, each Python block compiles)."""

from __future__ import annotations

import argparse
import re
import shlex
import sys
import tomllib

import pytest
from docs_util import ROOT, blocks, fenced, page, pages

sys.path.insert(0, str(ROOT / "tools"))

from softplc import PLC

pytest_plugins = ["pytester"]

# The commands shown in the pages' code blocks: `softplc NAME ...` at a line's start (after
# an optional `$ ` prompt), comments dropped.
COMMAND_LINE = re.compile(r"^(?:\$ )?(softplc [^#\n]*)", re.M)
SHELL = ("sh", "console", "text", "")


def copy_programs(pytester: pytest.Pytester, *globs: str) -> None:
    dst = pytester.path / "ladder_programs"
    dst.mkdir()
    for pattern in globs:
        for f in (ROOT / "ladder_programs").glob(pattern):
            (dst / f.name).write_text(f.read_text())


README_MAX_LINES = 200  # issue 32: a front page; the rest is the site (docs/)


def test_the_readme_is_a_front_page():
    readme = page("README.md")
    assert readme.count("\n") <= README_MAX_LINES
    for part in ("## Set-up: two commands", "make run", "make test", "## A first example",
                 "softplc check", "softplc run", "softplc io", "@pytest.mark.plc_program",
                 "(docs/index.md)"):
        assert part in readme, part


# ---- the README's first example: check, (run, operate: tests/e2e/test_first_hour.py), test ----
def test_readme_first_example_checks(capsys):
    from softplc.cli import main

    line = fenced(page("README.md"), "**Check** it", "sh").strip()
    assert line.startswith("softplc check ")
    import os

    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        assert main(shlex.split(line)[1:]) == 0
    finally:
        os.chdir(cwd)
    assert "error" not in capsys.readouterr().err


def test_readme_first_example_test_passes(pytester):
    pytester.makepyfile(test_star=fenced(page("README.md"), "**Test** it", "python"))
    copy_programs(pytester, "star_delta.*", "star_delta_symbols.csv")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)


# ---- the pages' examples ---------------------------------------------------------------------
def test_python_api_example(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    code = fenced(page("docs/getting-started.md"), "## Python API", "python")
    exec(compile(code, "docs/getting-started.md", "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == "0.61 61 RUN"  # as the comment in the page says
    x, z, pen = printed[1].split()
    assert (int(float(x)), int(float(z)), pen) == (1000, 500, "True")


def test_configuration_example_loads():
    cfg = tomllib.loads(fenced(page("docs/configuration.md"), "# Configuration", "toml"))
    plc = PLC.from_source("LD %I0.0\nIN %TM0\nLD %TM0.Q\nCU %C0\nLD %C0.D\nU %DR0\n"
                          "LD 1\n[ %MF4 := %KF2 * 2.0 ]\nI %R0\n", cfg)
    plc.scan(3)
    assert plc["%MF4"] == 3.0 and "X" in plc.devices


def test_pytest_plugin_example(pytester):
    pytester.makepyfile(test_user=fenced(
        page("docs/pytest.md"), "Installing softplc registers a pytest plugin", "python"))
    copy_programs(pytester, "drawing_table.*")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=2)


def test_servo_parameter_table_is_the_code_s():
    from softplc.devices.axis.law import markdown_table

    assert markdown_table() in page("docs/machines/servo-table.md")


# ---- every page ---------------------------------------------------------------------------------
def _options(parser: argparse.ArgumentParser) -> set[str]:
    """Every option string of a parser and of its nested subcommands."""
    found = set(parser._option_string_actions)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found |= _options(sub)
    return found


def _command_parser(name: str) -> argparse.ArgumentParser:
    from softplc.cli import build_parser

    top = build_parser(name)
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


COMMAND_LINES = sorted({(name, m.group(1).strip())
                        for lang in SHELL for name, _line, text in blocks(lang)
                        for m in COMMAND_LINE.finditer(text)})


def test_the_pages_show_commands():
    assert len(COMMAND_LINES) >= 40  # the pattern still finds the pages' command lines


@pytest.mark.parametrize("where, line", COMMAND_LINES)
def test_every_command_line_names_a_command_and_its_options(where, line):
    from softplc.cli import COMMAND_MODULES

    words = line.split()
    assert words[1] in COMMAND_MODULES, f"{where}: {line}"
    known = _options(_command_parser(words[1]))
    # `--name=value`, `--name value`; the `[--x]` of a synopsis too
    used = {w.strip("[]").split("=")[0] for w in words[2:] if w.strip("[]").startswith("--")}
    assert used <= known, f"{where}: {line}: unknown {sorted(used - known)}"


@pytest.mark.parametrize("where, line, text", blocks("toml"))
def test_every_toml_block_parses(where, line, text):
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        pytest.fail(f"{where}:{line}: {e}")


@pytest.mark.parametrize("where, line, text", blocks("python"))
def test_every_python_block_compiles(where, line, text):
    compile(text, f"{where}:{line}", "exec")


def test_every_code_block_says_its_language():
    untagged = [(name, line) for name, line, _text in blocks("")]
    assert not untagged, f"fenced code without a language: {untagged}"


def test_every_page_is_in_the_site_s_navigation():
    """By hand in mkdocs.yml, or, for the design records, by the build's hook."""
    nav = (ROOT / "mkdocs.yml").read_text()
    missing = [name for name in pages() if name.startswith("docs/")
               and not name.startswith("docs/decisions/")
               and name.removeprefix("docs/") not in nav]
    assert not missing, f"add them to the nav of mkdocs.yml: {missing}"


def test_every_design_record_has_a_title_and_a_decision():
    import mkdocs_hooks

    records = mkdocs_hooks.records(ROOT / "docs")
    assert len(records) >= 10
    for path in records:
        title, decision = mkdocs_hooks._summary(path.read_text(encoding="utf-8"))
        assert title and decision, f"{path.name}: a '# Title' and a '**Decision.**' paragraph"
    table = mkdocs_hooks.records_table(ROOT / "docs")
    assert "| [Our own Modbus framing](own-modbus-framing.md) | The server" in table


# a file of the repository named in a page (`softplc/plc.py`, `tests/unit/test_pid.py`,
# `ladder_programs/*.il`), as a path from the repository root
REPO_PATH = re.compile(r"(?<![\w/.])((?:softplc|tools|tests|ladder_programs|docs)/[\w./*-]*\w)")


def test_every_file_a_page_names_exists():
    texts = {**pages(), "CONTRIBUTING.md": page("CONTRIBUTING.md")}
    missing = sorted({(name, m.group(1)) for name, text in texts.items()
                      for m in REPO_PATH.finditer(text)
                      if not any(ROOT.glob(m.group(1))) and not any(ROOT.glob(m.group(1) + ".py"))})
    assert not missing, f"stale file names: {missing}"
