"""docs/symbols.md's examples run as written: the Python example prints what the page
says, the REPL transcript is the REPL's, the requirements load and hold, and the
hypothesis pattern passes in a separate pytest run (so the page cannot drift)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from softplc import PLC
from softplc.debug.repl import PROMPT
from softplc.debug.session import Session
from softplc.verify.requirements import load_spec

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parents[2]
PAGE = (ROOT / "docs" / "symbols.md").read_text()
STAR = ROOT / "ladder_programs" / "star_delta"


def blocks(after: str, lang: str) -> list[str]:
    """The ```lang blocks after the heading or sentence `after`, up to the next heading."""
    start = PAGE.index(after)
    end = PAGE.find("\n#", start + 1)
    return re.findall(rf"```{lang}\n(.*?)```", PAGE[start:end if end > 0 else None], re.S)


def star() -> PLC:
    return PLC.from_file(STAR.with_suffix(".il"), config=STAR.with_suffix(".toml"))


def test_the_declarations_are_a_valid_table(tmp_path):
    toml, csv = blocks("## Declaring symbols", "toml")[0], blocks("## Declaring symbols",
                                                                   "text")[0]
    (tmp_path / "star_delta_symbols.csv").write_text(csv)
    (tmp_path / "x.toml").write_text(toml)
    plc = PLC.from_source("LD START_PB\nST KM1_MAIN\nLD 1\n[ LINE_SPEED := STARTS ]\n",
                          tmp_path / "x.toml")
    assert plc.symbols.address_of("line_speed") == "%MW20"
    assert plc.symbols.label("%Q0.5") == "SPARE_LAMP(%Q0.5)"


def test_the_python_example_prints_what_the_page_says(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    code = blocks("The Python API, with", "python")[0]
    exec(compile(code, "docs/symbols.md", "exec"), {})
    expected = blocks("The Python API, with", "text")[0]
    assert capsys.readouterr().out == expected


def test_the_repl_transcript_is_the_repls():
    transcript = blocks("The REPL (`softplc repl ladder_programs", "text")[0].splitlines()
    s = Session(star())
    commands = [k for k, line in enumerate(transcript) if line.startswith(PROMPT)]
    assert commands
    for k, nxt in zip(commands, commands[1:] + [len(transcript)], strict=True):
        out = s.execute(transcript[k][len(PROMPT):])
        assert out.splitlines() == transcript[k + 1:nxt], transcript[k]


def test_the_requirements_load_and_name_the_objects(tmp_path):
    text = blocks("A requirement file for `softplc verify`", "toml")[0]
    assert tomllib.loads(text)["requirement"]
    req = ROOT / "ladder_programs" / "star_delta.req.toml"
    assert 'check = "never KM2_STAR AND KM3_DELTA"' in req.read_text()  # as the page says
    (tmp_path / "page.req.toml").write_text(text)
    spec = load_spec(tmp_path / "page.req.toml", [], star().symbols)
    assert [str(r) for r in spec.requirements[0].reads] == ["%Q0.1", "%Q0.2"]
    assert {r.symbol for r in spec.reads} >= {"KM2_STAR", "KM3_DELTA", "OVERLOAD_OK"}


def test_the_hypothesis_pattern_passes(pytester):
    code = blocks("## Property tests with hypothesis", "python")[0]
    pytester.makepyfile(test_page=code)
    dst = pytester.path / "ladder_programs"
    dst.mkdir()
    for f in (ROOT / "ladder_programs").glob("star_delta*"):
        (dst / f.name).write_text(f.read_text())
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)


EXAMPLES = ROOT / "ladder_programs"
# each example program with its configuration (the seed and the defect run on the others')
PAIRS = [(il, il.with_name(il.stem.replace("_seed", "").replace("_defect", "") + ".toml"))
         for il in sorted(EXAMPLES.glob("*.il"))] + [
    (EXAMPLES / "plant" / "master.il", EXAMPLES / "plant" / "master.toml"),
    (EXAMPLES / "plant" / "station.il", EXAMPLES / "plant" / "filler.toml"),
    (EXAMPLES / "plant" / "station.il", EXAMPLES / "plant" / "capper.toml")]


def test_every_example_program_names_its_inputs_and_outputs():
    """As the page says: every shipped program has a symbol table, and each %I / %Q it
    uses has a name."""
    from softplc.compiler.resolve import object_uses

    for il, config in PAIRS:
        plc = PLC.from_file(il, config, devices=False)
        io = [r for r in object_uses(plc.ast) if r.kind in ("I", "Q") and r.length is None]
        unnamed = [str(r) for r in io if plc.symbols.name_of(r) is None]
        assert io and not unnamed, f"{il.name} with {config.name}: {unnamed}"
