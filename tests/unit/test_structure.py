"""The structure rules (CONTRIBUTING.md, issue 22) hold on softplc/, as
`tools/check_structure.py` measures them: no file over 700 lines, no class over 25 methods
(tables of one method per instruction exempt), each block family named in at most 2 files
(its module and the catalog),
no import cycle between files (every import statement counted) nor between the top-level
packages (the runtime importing the compiler and the compiler the runtime would be one;
an import up the layers, as the runtime importing the compiler, is refused on its own),
nothing in web/ reaching the PLC object."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parents[2] / "tools"
sys.path.insert(0, str(TOOLS))

import check_structure  # noqa: E402


def test_the_structure_rules_hold():
    rep = check_structure.measure()
    assert rep.long_files == []
    assert rep.big_classes == []
    assert rep.cycles == []
    assert rep.package_cycles == []
    assert rep.web_reach == []
    assert rep.upward == []
    assert {k: v for k, v in rep.per_kind.items() if len(v) > check_structure.MAX_KIND_FILES} == {}
    assert rep.broken == 0
    assert all(rep.per_kind.values())  # the tree was read: the catalog names every kind


def test_the_checker_sees_what_it_counts(tmp_path):
    """A kind in a regex alternation or a key counts, one in a docstring does not; a
    factory-made method counts; a cycle between two files is found, through any import
    statement: module level, under `if TYPE_CHECKING:`, inside a function."""
    pkg = tmp_path / "softplc"
    (pkg / "web").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text('"""Mentions %PLS in prose."""\nfrom . import b\n'
                              'KINDS = r"TM|PLS|C"\n')
    (pkg / "b.py").write_text("from . import a\nX = {'PWM': 1}\n")
    (pkg / "web" / "__init__.py").write_text("")
    (pkg / "web" / "v.py").write_text("def f(ctl):\n    return ctl.plc.mem\n")
    methods = "\n".join(f"    def m{i}(self):\n        pass" for i in range(25))
    (pkg / "big.py").write_text(
        "from collections.abc import Callable\n\n"
        "def _make(n) -> Callable:\n    def f(self):\n        return n\n    return f\n\n"
        f"class Big:\n{methods}\n    extra = _make(1)\n")
    # a cycle through a TYPE_CHECKING import (a type hint), one through an import in a
    # function; `from . import sub` is an edge to sub alone (not to the package)
    (pkg / "hint.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                 "    from .hinted import Up\n")
    (pkg / "hinted.py").write_text("from .hint import *\nclass Up:\n    pass\n")
    (pkg / "late.py").write_text("def f():\n    from softplc.lazy import g\n    return g\n")
    (pkg / "lazy.py").write_text("import softplc.late\ndef g():\n    pass\n")
    (pkg / "__init__.py").write_text("from . import top\n")
    (pkg / "top.py").write_text("from . import leaf\n")
    (pkg / "leaf.py").write_text("X = 1\n")
    # no cycle between files, one between the packages p and q (p.x -> q.y, q.z -> p.w)
    for sub, text in (("p/x.py", "import softplc.q.y\n"), ("p/w.py", ""),
                      ("q/y.py", ""), ("q/z.py", "from ..p import w\n")):
        (pkg / sub).parent.mkdir(exist_ok=True)
        (pkg / sub).parent.joinpath("__init__.py").touch()
        (pkg / sub).write_text(text)
    rep = check_structure.measure(pkg)
    assert rep.per_kind["PLS"] == ["softplc/a.py"] and rep.per_kind["PWM"] == ["softplc/b.py"]
    assert sorted(rep.cycles) == [["softplc.a", "softplc.b"], ["softplc.hint", "softplc.hinted"],
                                  ["softplc.late", "softplc.lazy"]]
    assert sorted(rep.package_cycles) == [["softplc.a", "softplc.b"],
                                          ["softplc.hint", "softplc.hinted"],
                                          ["softplc.late", "softplc.lazy"],
                                          ["softplc.p", "softplc.q"]]
    assert rep.web_reach == ["softplc/web/v.py"]
    assert rep.big_classes == ["softplc/big.py:8 Big 26"]
    assert ast.parse((pkg / "big.py").read_text())  # the sample itself is valid Python


def test_every_family_is_counted_and_where_its_kind_goes(tmp_path):
    """Every block family is counted, the basic ones included. A one-letter kind counts
    where a kind goes (a key of `blocks`, a `kind` test, `family(...)`, an address "%C{i}"),
    not as a pin or a field ("R" resets) nor as the date format "%R"; an example in a
    sentence (a message) does not count, a format does; a module importing a family's
    runtime class by name names the family."""
    assert {"TM", "C", "DR", "SBR", "SC", "R", "PLS", "PWM", "FC", "VFC", "PID"} <= \
        set(check_structure.KINDS)
    pkg = tmp_path / "softplc"
    (pkg / "twido").mkdir(parents=True)
    (pkg / "blocks").mkdir()
    for d in (pkg, pkg / "twido", pkg / "blocks"):
        (d / "__init__.py").write_text("")
    (pkg / "twido" / "catalog.py").write_text(
        "from dataclasses import dataclass\n\n@dataclass(frozen=True)\nclass Family:\n"
        "    kind: str\n    runtime: str\n\n"
        "FAMILIES = {f.kind: f for f in (Family('C', 'softplc.blocks.counter:Counter'),)}\n")
    (pkg / "blocks" / "counter.py").write_text("class Counter:\n    PINS = ('R', 'CU')\n")
    (pkg / "pins.py").write_text("PINS = ('R', 'S')\nFIELDS = {'C': 1}\n"
                                 "STAMP = '%H:%R'\ndef r(self, v):\n    pass\n")
    (pkg / "keys.py").write_text("def f(mem):\n    return mem.blocks['C']\n")
    (pkg / "test.py").write_text("def f(ref):\n    return ref.kind == 'R'\n")
    (pkg / "fmt.py").write_text("def f(i):\n    return f'%C{i}'\n")
    (pkg / "message.py").write_text("HINT = 'a full address such as %C0.D'\n")
    (pkg / "user.py").write_text("from softplc.blocks.counter import Counter\n")
    rep = check_structure.measure(pkg)
    assert rep.per_kind["C"] == ["softplc/blocks/counter.py", "softplc/fmt.py",
                                 "softplc/keys.py", "softplc/twido/catalog.py",
                                 "softplc/user.py"]
    assert rep.per_kind["R"] == ["softplc/test.py"]


def test_the_layers_refuse_an_upward_import_and_one_machine_reaching_another():
    graph = {"softplc.runtime.engine": {"softplc.twido.address", "softplc.web.server"},
             "softplc.machines.cutting.client": {"softplc.machines.gcode.parser",
                                                 "softplc.machines.servo.client",
                                                 "softplc.modbus_codec"},
             "softplc.web.live": {"softplc.machines.machining.handshake"}}
    assert check_structure.upward_imports(graph) == [
        "softplc.machines.cutting.client -> softplc.machines.servo.client",
        "softplc.runtime.engine -> softplc.web.server",
        "softplc.web.live -> softplc.machines.machining.handshake"]
    assert check_structure.layer_of("softplc.machines.drawing.pen") > \
        check_structure.layer_of("softplc.commands.run") > check_structure.layer_of("softplc.il")
