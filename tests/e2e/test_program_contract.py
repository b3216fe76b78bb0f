"""The contract between compiled code and the runtime (softplc/program.py).

Every name generated code refers to is in the one bindings table; an edge-heavy program
runs; a fault inside compiled code puts the PLC in HALT. (That the package graph has no
cycle and the runtime does not import the compiler is tools/check_structure.py's to
check: tests/unit/test_structure.py.)
"""

from __future__ import annotations

import ast
import builtins
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient
from test_fuzz import CONFIG, line, rung

from softplc import PLC, ProgramError
from softplc.modbus import ModbusImage, ServerThread
from softplc.program import Names
from softplc.twido.semantics import FUNCTIONS

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = sorted((ROOT / "ladder_programs").glob("*.il"))


def free_names(source: str) -> set[str]:
    """Names generated code reads that it does not define itself (globals of the module)."""
    tree = ast.parse(source)
    defined = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    free: set[str] = set()
    for fn in (n for n in tree.body if isinstance(n, ast.FunctionDef)):
        params = {a.arg for a in fn.args.args}
        local = params | {t.id for n in ast.walk(fn) for t in
                          ([n.target] if isinstance(n, (ast.AugAssign, ast.For, ast.comprehension,
                                                   ast.NamedExpr))
                           else getattr(n, "targets", [])) if isinstance(t, ast.Name)}
        for default in fn.args.defaults:  # `_MW=_MW`: bound from the namespace
            free |= {n.id for n in ast.walk(default) if isinstance(n, ast.Name)}
        for body in fn.body:
            free |= {n.id for n in ast.walk(body) if isinstance(n, ast.Name)
                     and isinstance(n.ctx, ast.Load) and n.id not in local}
    return free - defined - set(dir(builtins))


def assert_contract(plc: PLC) -> None:
    for compiled in (plc.program, plc.compile_debug()):
        names = free_names(compiled.source)
        unbound = sorted(n for n in names if not Names.is_bound(n))
        assert not unbound, f"generated code uses names outside the bindings table: {unbound}"
        missing = sorted(n for n in names if n not in compiled.namespace)
        assert not missing, f"bindings table names not bound by the PLC: {missing}"


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_every_emitted_name_is_in_the_bindings_table(path):
    toml = path.with_suffix(".toml")
    if not toml.exists():  # the seed program runs on the drawing table's configuration
        toml = path.with_name(path.stem.split("_seed")[0] + ".toml")
    plc = PLC.from_file(path, config=toml, devices=False)
    assert_contract(plc)


def _function_call(name: str) -> str:
    params, result = FUNCTIONS[name]
    if params == ("table",):
        return f"[ %MF20 := {name}( %MF0:4 ) ]"
    args = {"num": "%MF10", "int": "%MW10", "INT": "%MW10", "DINT": "%MD12", "REAL": "%MF14"}
    real_args = ", ".join(args.get(p, args.get(str(p).upper(), "%MW11")) for p in params)
    target = {"INT16": "%MW30", "INT32": "%MD32"}.get(str(result).upper(), "%MF34")
    if result == "same":
        target = "%MF34" if params[0] == "num" else "%MW30"
    return f"[ {target} := {name}( {real_args} ) ]"


def test_every_function_and_instruction_binds():
    """One program using every instruction family and every function of semantics."""
    calls = "\n".join(_function_call(f) for f in sorted(FUNCTIONS) if f not in ("SHL", "SHR",
                                                                               "ROL", "ROR"))
    src = f"""
LDR %I0.0
ANDF %M1
OR( %M2
ANDR %M3
)
XORN %M4
MPS
ST %Q0.0
MPP
STN %Q0.1
LD 1
{calls}
[ %MW40 := SHL( %MW41, 2 ) ]
[ %MD42 := ROR( %MD44, 3 ) ]
[ %MW46 := %MW47 * %MW48 / 3 REM 2 - -%MW49 ]
[ %MD50 := %MD52 + 70000 ]
[ %MF54 := %MF56 / 2.0 ]
[ %MW60[%MW61] := 7 ]
[ %MD62[%MW61] := 7 ]
[ %MW70:4 := %MW80:4 ]
[ %M100:8 := %MW90 ]
[ %MW91 := %M100:8 ]
[ INC %MW92 ]
ST %MW93:X4
LD [ %MW94 > %KW0 ]
CU %C0
LD %C0.D
SR0
LD 1
JMPC %L1
%L1:
LD %TM0.Q
IN %TM0
END
SR0:
LD 1
RET
"""
    plc = PLC.from_source(src, {"timers": {"%TM0": {"type": "TON", "base": "10ms",
                                                    "preset": 3}}})
    plc.scan(2)
    assert plc.state == "RUN"
    assert_contract(plc)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(rung, min_size=1, max_size=12))
def test_generated_programs_keep_the_contract(rungs):
    plc = PLC.from_source("%L1:\n" + "\n".join(ln for r in rungs for ln in r) + "\n", CONFIG)
    assert_contract(plc)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(line, max_size=20))
def test_random_programs_keep_the_contract(lines):
    try:
        plc = PLC.from_source("\n".join(lines) + "\n", CONFIG)
    except ProgramError:
        return
    assert_contract(plc)


# ---- bugs the contract fixed -------------------------------------------------------------------
def test_more_than_4096_edge_instructions_run():
    n = 4200  # edge memory used to be a fixed 4,096 cells
    src = "".join(f"LDR %M{k % 100}\nST %M{100 + k % 100}\n" for k in range(n))
    plc = PLC.from_source(src)
    plc["%M5"] = 1
    plc.scan()
    assert plc.state == "RUN", plc.fault
    assert plc["%M105"] == 1
    assert len(plc.program_state.edges) >= n
    plc.scan()
    assert plc["%M105"] == 0  # the edge was seen once


def _faulty_plc() -> PLC:
    plc = PLC.from_source("LD %M0\nCU %C0\nLD 1\n[ %MW1 := %MW0 + 1 ]\n")

    def broken(value: int) -> None:  # a fault inside compiled code, when %M0 is set
        if value:
            raise ValueError("simulated fault")

    plc.mem.blocks["C"][0].cu = broken
    return plc


def test_a_fault_inside_compiled_code_halts_with_the_fault_recorded():
    plc = _faulty_plc()
    plc["%M0"] = 1
    plc.scan()  # does not raise
    assert plc.state == "HALT"
    assert "ValueError" in plc.fault and "simulated fault" in plc.fault
    assert plc["%SW30"] >= 0 and plc.scan_count == 1  # scan statistics still kept
    plc["%MW0"] = 5
    plc.scan(2)  # in HALT the program no longer runs
    assert plc.state == "HALT" and plc["%MW1"] == 0


def test_a_fault_in_the_debug_build_halts_too():
    plc = _faulty_plc()
    plc["%M0"] = 1
    dbg = plc.compile_debug()
    for _ in plc.engine.scan_stepwise(dbg.main):
        pass
    assert plc.state == "HALT" and "simulated fault" in plc.fault


def test_modbus_keeps_serving_after_a_fault():
    plc = _faulty_plc()
    img = ModbusImage(plc.mem)
    plc.before_scan.append(img.apply_writes)
    plc.after_scan.append(img.take_snapshot)
    server = ServerThread(img, "127.0.0.1", 0).start()
    try:
        plc["%MW0"] = 41
        plc.scan()
        assert plc["%MW1"] == 42 and plc.state == "RUN"
        plc["%M0"] = 1
        plc.scan()
        assert plc.state == "HALT"
        client = ModbusTcpClient("127.0.0.1", port=server.port, timeout=2)
        assert client.connect()
        try:
            assert client.read_holding_registers(1, count=1).registers == [42]
            assert not client.write_register(5, 7).isError()
            plc.scan()  # HALT: writes still applied at the scan boundary
            assert plc["%MW5"] == 7 and plc.state == "HALT"
        finally:
            client.close()
    finally:
        server.stop()
