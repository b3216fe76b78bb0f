"""Ladder rendering: snapshot tests of the text drawing, the live view, SVG, the CLI.

Run with SOFTPLC_UPDATE_SNAPSHOTS=1 to rewrite tests/snapshots/ after a deliberate change.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from softplc import ladder
from softplc.cli import main
from softplc.debug.session import Session
from softplc.il import ast as A
from softplc.il import rungtree
from softplc.il.parser import parse, parse_file
from softplc.plc import PLC

HERE = Path(__file__).parents[1]  # tests/
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
    assert "[ INC %MW0 ]" in texts and "[%C0 CU]" not in texts
    # the counter block is one box: its name once, its pins inside
    assert texts.count("%C0") == 1 and {"R", "CU", "CD", "S", "E", "D", "F"} <= set(texts)
    assert len(list(root.iter("{http://www.w3.org/2000/svg}path"))) >= 10  # coil arcs


BLOCKS = """(*RUNG: timer block*)
BLK   %TM0
LD    %I0.1
IN
OUT_BLK
LD    Q
ST    %Q0.3
END_BLK

(*RUNG: counter block*)
BLK   %C0
LD    %I0.0
R
LD    %I0.1
AND   %M1
CU
LDN   %I0.2
CD
OUT_BLK
LD    D
ST    %Q0.1
LD    F
AND   %M2
S     %M3
END_BLK

(*RUNG: OR after an output*)
LD    %I0.3
ST    %Q0.4
OR    %I0.4
ST    %Q0.5

(*RUNG: ORN after an output and more logic*)
LD    %I0.5
AND   %M4
ST    %Q0.6
ORN   %I0.6
AND   %M5
ST    %Q0.7
"""
BLOCKS_CONFIG = {"scan_period": "10ms",
                 "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 5}},
                 "counters": {"%C0": {"preset": 1}}}


def test_blocks_and_or_after_output_snapshot() -> None:
    check_snapshot("blocks.txt", ladder.render_program_text(parse(BLOCKS)))


def test_blocks_live_snapshot() -> None:
    """%I0.1 forced on for 10 scans: the timer is done, the counter counted once (D)."""
    s = Session(PLC.from_source(BLOCKS, config=BLOCKS_CONFIG))
    for cmd in ("force %I0.1 1", "force %I0.2 1", "set %M1 1", "set %M5 1",
                "force %I0.6 1", "scan 10"):
        s.execute(cmd)
    views = "\n".join(s.execute(f"rung {i}") for i in range(len(s.plc.rungs)))
    check_snapshot("blocks_live.txt", views + "\n")
    timer = views.split("rung 1")[0]
    # power through the IN pin, out of Q to the coil; type, base, preset inside the box
    assert "┤IN" in timer and "═┤IN" in timer and "Q├════( )" in timer
    assert "TON 10ms" in timer and "P=5 V=5" in timer


def test_function_block_is_one_box() -> None:
    rung = parse(BLOCKS).rungs[1]
    text = ladder.render_text(rung, header=False)
    lines = text.splitlines()
    assert text.count("%C0") == 1 and "[%C0" not in text  # one box, titled once
    assert lines[0].split("┌")[1].startswith("─%C0") and "└" in lines[-1]
    # the pins in TwidoSuite's order, each input's network on its left
    row = {pin: next(i for i, ln in enumerate(lines) if f"┤{pin} " in ln or f"│{pin} " in ln)
           for pin in ("R", "S", "CU", "CD")}
    assert row["R"] < row["S"] < row["CU"] < row["CD"]
    assert "%I0.1" in lines[row["CU"] - 1] and "%M1" in lines[row["CU"] - 1]
    assert "┤/├" in lines[row["CD"]] and "│S " in lines[row["S"]]  # S is not wired
    # the outputs on the right, leading to the coils that use them
    assert "D├" in lines[row["S"]] and "( )" in lines[row["S"]]
    assert "F├" in lines[row["CU"]] and "(S)" in lines[row["CU"]]
    assert "E│" in lines[row["R"]]  # E is not used


def test_or_after_an_output_draws_each_contact_once() -> None:
    for rung in parse(BLOCKS).rungs[2:]:
        text = ladder.render_text(rung, header=False)
        for ins in rung.instructions:
            if hasattr(ins, "operand"):
                assert text.count(str(ins.operand.ref)) == 1, (str(ins.operand.ref), text)
    # LD a / ST b / OR c / ST d: a feeds b alone, (a OR c) feeds d
    lines = ladder.render_text(parse(BLOCKS).rungs[2], header=False).splitlines()
    assert lines[1].startswith("├──┤ ├──┬") and lines[1].endswith("( )──┤")
    assert lines[3].lstrip("│ ").startswith("└─────┬") and "( )" in lines[3]
    assert lines[5].startswith("├──┤ ├────────┘")


def test_or_after_an_output_that_would_cross_is_drawn_apart() -> None:
    # MPS / ST / OR / ST / MPP / ST: the OR is drawn after the MPP branch, not across it
    rung = parse("LD %I0.0\nMPS\nST %Q0.0\nOR %I0.1\nST %Q0.1\nMPP\nST %Q0.2\n").rungs[0]
    text = ladder.render_text(rung, header=False)
    assert text.count("%I0.0") == 1 and "┼" not in text
    assert text.index("%Q0.2") < text.index("%Q0.1")


def _drawn_coils(g: ladder.Grid, state: dict[str, bool]) -> dict[int, bool]:
    """Power at each coil of a laid-out rung, read the ladder way (power flows left to
    right; a vertical link joins the rows it spans into one node)."""
    power: dict[tuple[int, int], bool] = {}
    coils: dict[int, bool] = {}
    for b in range(g.outcol + 2):
        into: dict[int, bool] = {}
        for r in range(g.rows):
            cell = g.cells.get((r, b - 1))
            if b == 0:
                into[r] = True
            elif cell is not None and cell.box is not None:
                if cell.box.right_wired:
                    into[r] = state[f"{cell.elem.symbol}.{cell.box.right}"]
            elif cell is not None and (cell.elem is None or cell.elem.kind == "contact"):
                on = cell.elem is None or state[str(cell.elem.ref)] != (cell.elem.symbol == "┤/├")
                into[r] = power[(r, b - 1)] and on
        node = list(range(g.rows))
        for col, r1, r2, _ in g.vlinks:
            if col == b:
                for r in range(r1 + 1, r2 + 1):
                    old, new = node[r], node[r1]
                    node = [new if n == old else n for n in node]
        for r in range(g.rows):
            power[(r, b)] = any(p for rr, p in into.items() if node[rr] == node[r])
            cell = g.cells.get((r, b))
            if cell is not None and cell.elem is not None and cell.elem.kind == "coil":
                coils[cell.elem.k] = power[(r, b)]
    return coils


@pytest.mark.parametrize("src", [
    BLOCKS,
    "LD %I0.0\nST %Q0.0\nOR %I0.1\nAND %M1\nORN %I0.2\nST %Q0.1\nST %Q0.2\n",
    "LD %I0.0\nOR %M1\nST %Q0.0\nAND %M3\nOR( %I0.1\nAND %M4\n)\nST %Q0.1\n",
    "LD %I0.0\nMPS\nAND %M0\nST %Q0.0\nOR %M1\nST %Q0.1\nMPP\nST %Q0.2\n",
    "LD %I0.0\nMPS\nST %Q0.0\nOR %I0.1\nST %Q0.1\nMPP\nAND %M2\nST %Q0.2\n",
    "BLK %C0\nLD %I0.0\nCU\nOUT_BLK\nLD D\nST %Q0.0\nOR %M1\nST %Q0.1\nEND_BLK\n",
])
def test_the_drawing_computes_what_the_il_computes(src: str) -> None:
    """Every coil, for every state of the contacts and block outputs, gets the power the
    IL's accumulator has at its ST: the drawing connects exactly what the IL connects."""
    for rung in PLC.from_source(src + "END\n", config=BLOCKS_CONFIG).ast.rungs:  # it compiles
        names = sorted({str(i.operand.ref) for i in rung.instructions
                        if isinstance(getattr(i, "operand", None), A.Operand)} |
                       {f"{i.block}.{f}" for i in rung.instructions
                        if isinstance(i, A.Blk) for f in ladder.BOX_PINS[i.block.kind][1]})
        grid = ladder.layout(rung)
        for bits in range(1 << len(names)):
            state = {n: bool(bits >> i & 1) for i, n in enumerate(names)}
            drawn, acc = _drawn_coils(grid, state), _il_accumulator(rung, state)
            assert acc and drawn == acc, (rung.index, state)


def _il_accumulator(rung: A.Rung, state: dict[str, bool]) -> dict[int, bool]:
    """The accumulator at each output, by the IL's rules (LD AND OR, parentheses, MPS),
    evaluated here on its own; what each `)`, MRD and MPP refers to comes from the rung
    structure (`il.rungtree`, tested in test_rungtree.py and through compiled behaviour)."""
    acc, saved, out = False, {}, {}
    for st in rungtree.build(rung).steps:
        ins = st.instr
        if isinstance(ins, (A.BoolInstr, A.ParenOpen)):
            op = ins.operand
            v = state[f"{st.block}.{op.name}" if isinstance(op, A.BlockOutput) else str(op.ref)]
            v = v != (ins.modifier == "N")
            if isinstance(ins, A.ParenOpen):
                saved[st.k], acc = acc, v
            else:
                acc = v if ins.op == "LD" else (acc and v) if ins.op == "AND" else (acc or v)
        elif isinstance(ins, A.ParenClose):
            outer = saved[st.opener]
            acc = (outer and acc) if rung.instructions[st.opener].op == "AND" else (outer or acc)
        elif isinstance(ins, A.Stack):
            if ins.op == "MPS":
                saved[st.k] = acc
            else:
                acc = saved[st.opener]
        elif isinstance(ins, A.Store):
            out[st.k] = acc
    return out


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


def test_svg_box_configuration_clear_of_the_pin_names(tmp_path):
    """`ladder --config`: the block's "TOF 100ms" line sits below the IN pin's name (it
    used to overlap it) and inside the box."""
    prog = tmp_path / "tof.il"
    prog.write_text("BLK   %TM1\nLD    %I0.1\nIN\nOUT_BLK\nLD    Q\nST    %Q0.1\nEND_BLK\n")
    cfg = tmp_path / "tof.toml"
    cfg.write_text('timers."%TM1" = { type = "TOF", base = "100ms", preset = 20 }\n')
    out = tmp_path / "tof.svg"
    assert main(["ladder", str(prog), "--config", str(cfg), "--svg", str(out)]) == 0
    ns = {"s": "http://www.w3.org/2000/svg"}
    root = ET.parse(out).getroot()
    texts = {t.text: t for t in root.iterfind(".//s:text", ns)}
    pin, info = texts["IN"], texts["TOF 100ms"]
    pin_base = float(pin.get("y"))
    info_top = float(info.get("y")) - 0.75 * float(info.get("font-size"))  # cap height
    assert info_top >= pin_base + 2, (pin_base, info_top)
    box_bottom = max(float(ln.get("y2")) for ln in root.iterfind(".//s:line", ns)
                     if ln.get("y1") == ln.get("y2")
                     and float(ln.get("x1")) < float(info.get("x")) < float(ln.get("x2")))
    assert float(info.get("y")) < box_bottom


# ---- what a rung reads, from the rung tree -------------------------------------------------
def _drawn_reads(rung: A.Rung) -> set:
    """What drawing the rung live reads (the oracle: a reader that records every object)."""
    seen: set = set()

    def record(ref):
        seen.add(ref)
        return 0

    ladder.render_rung_svg(rung, ladder.Live(record, None))
    ladder.render_text(rung, ladder.Live(record, None))
    return seen


PROGRAMS = sorted((HERE.parent / "ladder_programs").rglob("*.il")) + [SAMPLE]


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_reads_are_what_the_live_view_shows(path: Path) -> None:
    """`ladder.reads` (from `il/rungtree.py`, no drawing) lists exactly the objects the live
    view of each rung of the shipped programs reads, each once."""
    for rung in parse_file(path).rungs:
        got = ladder.reads(rung)
        assert len(got) == len(set(got)), rung.name
        assert set(got) == _drawn_reads(rung), rung.name


def test_reads_of_a_block_a_comparison_and_an_operation() -> None:
    box, op = parse("BLK %C0\nLD %I0.0\nCU\nOUT_BLK\nLD D\nAND [ %MW1 + 2 > -%MW2 ]\n"
                    "ST %Q0.0\nEND_BLK\nLD %M3\n[ %MW4 := %MW5 * 2 ]\n").rungs
    # the box (the block, its output pins), the input, the comparison's objects, the coil
    assert [str(r) for r in ladder.reads(box)] == ["%C0", "%C0.E", "%C0.D", "%C0.F", "%I0.0",
                                                   "%MW1", "%MW2", "%Q0.0"]
    # an operation block shows its target's value, not its operands'
    assert [str(r) for r in ladder.reads(op)] == ["%M3", "%MW4"]


def test_reads_cover_random_rungs() -> None:
    """Random (also malformed) rungs: every object the drawing reads is listed (an
    unfinished load that a later LD replaces is listed though not drawn)."""
    from fuzz_budget import examples
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st
    from test_fuzz import line, rung

    from softplc.errors import SoftPLCError

    @settings(max_examples=examples(400), deadline=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(st.lists(st.one_of(line, rung.map("\n".join)), max_size=20))
    def check(lines: list[str]) -> None:
        try:
            prog = parse("\n".join(lines) + "\n")
        except SoftPLCError:
            return
        for r in prog.rungs:
            assert set(ladder.reads(r)) >= _drawn_reads(r), r.instructions

    check()


def test_the_ladder_package_stands_apart_from_the_debugger() -> None:
    """softplc.ladder imports neither the debugger nor the web monitor (both use it)."""
    import ast as pyast

    pkg = HERE.parent / "softplc" / "ladder"
    for f in pkg.glob("*.py"):
        for node in pyast.walk(pyast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, pyast.ImportFrom):
                mod = "." * node.level + (node.module or "")
                assert not mod.startswith(("..debug", "..web", "softplc.debug", "softplc.web",
                                           "..plc", "softplc.plc")), (f.name, mod)


def test_the_web_monitor_finds_a_rungs_reads_without_drawing_it(monkeypatch) -> None:
    """The web monitor's list of what a rung shows comes from the rung tree: no layout."""
    import importlib

    from softplc.web import ladderview

    lay = importlib.import_module("softplc.ladder.layout")  # (the package names a function so)

    def no_drawing(*args, **kw):
        raise AssertionError("the rung was drawn")

    monkeypatch.setattr(lay, "build", no_drawing)
    rung = parse_file(SAMPLE).rungs[1]  # threshold: LD [ %MW0 >= 3 ] / ST %M5
    assert [str(r) for r in ladderview.refs(rung)] == ["%MW0", "%M5"]
    with pytest.raises(AssertionError, match="drawn"):  # (the patch is where drawing goes)
        ladder.render_rung_svg(rung)
