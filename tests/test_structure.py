"""The structure rules (CONTRIBUTING.md, issue 22) hold on softplc/, as
`tools/check_structure.py` measures them: no file over 700 lines, no class over 25 methods
(tables of one method per instruction exempt), each block kind named in at most 3 files,
no import cycle between files, nothing in web/ reaching the PLC object."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parent.parent / "tools"
sys.path.insert(0, str(TOOLS))

import check_structure  # noqa: E402


def test_the_structure_rules_hold():
    rep = check_structure.measure()
    assert rep.long_files == []
    assert rep.big_classes == []
    assert rep.cycles == []
    assert rep.web_reach == []
    assert {k: v for k, v in rep.per_kind.items() if len(v) > check_structure.MAX_KIND_FILES} == {}
    assert rep.broken == 0


def test_the_checker_sees_what_it_counts(tmp_path):
    """A kind in a regex alternation or a key counts, one in a docstring does not; a
    factory-made method counts; a cycle between two files is found."""
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
    rep = check_structure.measure(pkg)
    assert rep.per_kind["PLS"] == ["softplc/a.py"] and rep.per_kind["PWM"] == ["softplc/b.py"]
    assert rep.cycles == [["softplc.a", "softplc.b"]]
    assert rep.web_reach == ["softplc/web/v.py"]
    assert rep.big_classes == ["softplc/big.py:8 Big 26"]
    assert ast.parse((pkg / "big.py").read_text())  # the sample itself is valid Python
