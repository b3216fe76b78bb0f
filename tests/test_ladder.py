"""Ladder rendering: snapshot tests of the text drawing, the live view, SVG, the CLI.

Run with SOFTPLC_UPDATE_SNAPSHOTS=1 to rewrite tests/snapshots/ after a deliberate change.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from softplc.cli import main
from softplc.debug import ladder
from softplc.debug.session import Session
from softplc.il.parser import parse, parse_file
from softplc.plc import PLC

HERE = Path(__file__).parent
SNAPSHOTS = HERE / "snapshots"
SAMPLE = HERE / "debug_sample.il"
CONFIG = {"scan_period": "10ms",
          "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 5}}}


def check_snapshot(name: str, text: str) -> None:
    path = SNAPSHOTS / name
    if os.environ.get("SOFTPLC_UPDATE_SNAPSHOTS") == "1" or not path.exists():
        path.parent.mkdir(exist_ok=True)
        path.write_text(text, encoding="utf-8")
        if os.environ.get("SOFTPLC_UPDATE_SNAPSHOTS") != "1":
            pytest.fail(f"snapshot {name} was missing and has been written: check it")
    assert text == path.read_text(encoding="utf-8"), \
        f"{name} differs (SOFTPLC_UPDATE_SNAPSHOTS=1 rewrites it)"


def test_program_text_snapshot() -> None:
    check_snapshot("debug_sample.txt", ladder.render_program_text(parse_file(SAMPLE)))


def test_program_ascii_snapshot() -> None:
    text = ladder.render_program_text(parse_file(SAMPLE), ascii=True)
    assert all(ord(c) < 128 for c in text)
    check_snapshot("debug_sample_ascii.txt", text)


def test_live_view_snapshot() -> None:
    """A fixed state: %MW0 = 3 (so %M5), %M7 forced, one scan."""
    s = Session(PLC.from_file(SAMPLE, config=CONFIG), SAMPLE)
    s.execute("set %MW0 3")
    s.execute("force %M7 1")
    s.execute("scan 2")
    views = "\n".join(s.execute(f"rung {i}") for i in range(len(s.plc.rungs)))
    check_snapshot("debug_sample_live.txt", views + "\n")


def test_parallel_branches_and_coils() -> None:
    rung = parse("LD %M0\nOR %M1\nAND( %M2\nORN %M3\n)\nST %Q0.0\nS %M4\n").rungs[0]
    text = ladder.render_text(rung, header=False)
    lines = text.splitlines()
    # OR draws %M1 under %M0, the parenthesis a second parallel pair, two coils on the right
    assert "%M0" in lines[0] and "%M2" in lines[0] and "%Q0.0" in lines[0]
    assert "┤ ├" in lines[1] and "( )" in lines[1] and lines[1].endswith("┤")
    assert "┤/├" in lines[3] and "(S)" in lines[3]


def test_power_flow_follows_the_accumulator_log() -> None:
    rung = parse("LD %M0\nAND %M1\nST %Q0.0\n").rungs[0]
    values = {"%M0": 1, "%M1": 0, "%Q0.0": 0}
    live = ladder.Live(lambda r: values[str(r)], [1, 0, 0])
    wire = ladder.render_text(rung, live, header=False).splitlines()[1]
    # powered from the rail through %M0, not after %M1
    assert wire.startswith("├═") and "═┤ ├══" in wire and wire.split("┤ ├")[2].startswith("─")


def test_every_drawing_table_rung_renders() -> None:
    table = HERE.parent / "ladder_programs" / "drawing_table.il"
    if not table.exists():
        pytest.skip("drawing table program not there")
    prog = parse_file(table)
    text = ladder.render_program_text(prog)
    for r in prog.rungs:
        assert f"rung {r.index}  {r.title}" in text


def test_svg_is_well_formed_with_titles_and_elements() -> None:
    svg = ladder.render_program_svg(parse_file(SAMPLE))
    root = ET.fromstring(svg)
    texts = [t.text for t in root.iter("{http://www.w3.org/2000/svg}text")]
    assert "rung 2  branches" in texts and "%Q0.0" in texts
    assert "[ INC %MW0 ]" in texts and "[%C0 CU]" in texts
    assert len(list(root.iter("{http://www.w3.org/2000/svg}path"))) >= 10  # coil arcs


def test_cli_ladder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ladder", str(SAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "rung 0  count: one more on each rising edge of %I0.0" in out
    assert main(["ladder", str(SAMPLE), "--svg", str(tmp_path / "l.svg")]) == 0
    assert (tmp_path / "l.svg").read_text().startswith("<svg")
    assert main(["ladder", str(SAMPLE), "--txt", str(tmp_path / "l.txt"), "--ascii",
                 "--rung", "stack"]) == 0
    txt = (tmp_path / "l.txt").read_text()
    assert "rung 3  stack" in txt and "rung 2" not in txt
    assert main(["ladder", str(SAMPLE), "--rung", "99"]) == 1
    assert "no rung '99'" in capsys.readouterr().err
