"""A long function is compiled in parts it calls in turn (compiler/codegen.py,
PART_LINES; issue 26's compile time): the parts compute what one function does, and a
rung that may end the scan (END, ENDC, RET) keeps everything after it in the caller."""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.compiler import codegen

RUNGS = 120


def _program(end: str) -> str:
    """Rungs of word arithmetic, edges, set/reset and a subroutine, `end` half-way."""
    out: list[str] = []
    for k in range(RUNGS):
        a, b, q = k % 7, (k * 3) % 11, 20 + k % 30
        out += [f"LD %I0.{k % 4}", f"ANDN %M{b}", f"[ %MW{k % 40} := %MW{(k + 1) % 40} + {k} ]",
                f"LDR %M{a}", f"OR [ %MW{k % 40} > {k * 50} ]", f"ST %M{q}",
                f"LD %M{q}", f"S %M{b}", f"LDN %I0.{(k + 1) % 4}", f"R %M{a}"]
        if k == RUNGS // 2:
            out += [end, "LD 1", "SR0"]
    out += ["END", "SR0:", "LD 1", "[ INC %MW45 ]", "LD %M2", "RETC", "[ INC %MW46 ]", "RET"]
    return "\n".join(out) + "\n"


def _run(text: str) -> tuple[list[int], list[int], str]:
    plc = PLC.from_source(text)
    for scan in range(40):
        for i in range(4):
            plc[f"%I0.{i}"] = (scan >> i) & 1
        plc.scan()
    return ([plc[f"%M{i}"] for i in range(60)], [plc[f"%MW{i}"] for i in range(50)],
            plc.program.source)


def _parts(source: str) -> list[str]:
    """The bodies of the generated part functions."""
    return [d.split("\n", 1)[1] for d in source.split("def ")[1:] if "_part" in d[:20]]


@pytest.mark.parametrize("end", ["LD %I0.2\nENDC", "LD %I0.3\nENDCN", "NOP"])
def test_parts_compute_what_one_function_does(end: str, monkeypatch: pytest.MonkeyPatch
                                              ) -> None:
    text = _program(end)
    whole = _run(text)
    monkeypatch.setattr(codegen, "PART_LINES", 40)
    parts = _run(text)
    assert not _parts(whole[2]) and len(_parts(parts[2])) >= 3
    assert parts[:2] == whole[:2]
    assert whole[1][45] > 0  # the subroutine ran
    # a part never returns (END/ENDC would end only that part): what follows the first
    # rung that may end the scan stays in `_main` itself
    assert not any("return" in p for p in _parts(parts[2]))


def test_end_half_way_ends_the_scan_with_parts(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(codegen, "PART_LINES", 40)
    ended, full = _run(_program("LD 1\nENDC")), _run(_program("NOP"))
    assert ended[1][45] == 0 and full[1][45] == 40  # SR0 is called after the ENDC
    assert ended[1] != full[1]
