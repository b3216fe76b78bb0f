"""The bit images (%I %Q %M %S %X, field and image) hold Python bools, never 0/1 ints
(issue 26: a conditional jump on a bool skips the truth test of an int). Every writer is
exercised: the generated code, the scan (latch, publish, system bits, forcing), host
writes, devices, blocks, Modbus coil writes, snapshots and the state file. What users
read stays 0/1-valued."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from softplc.modbus.image import ModbusImage
from softplc.persist import retain
from softplc.plc import PLC
from softplc.runtime.memory import MemoryImage

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
from bench_engine import config_for  # noqa: E402

BIT_LISTS = ("i", "i_field", "q", "q_field", "m", "s", "x")


def non_bools(mem: MemoryImage) -> list[str]:
    """Every bit image entry that is not a bool, as %KIND[index]=value."""
    return [f"{name}[{k}]={v!r}" for name in BIT_LISTS
            for k, v in enumerate(getattr(mem, name)) if type(v) is not bool]


def exercise(plc: PLC, scans: int = 30) -> None:
    """Scans with the inputs in use toggled, a forced bit and host writes between them."""
    inputs = sorted(plc.mem.io_used("I"))[:8]
    plc["%M200"] = 1
    plc.force("%M201", 1)
    for n in range(scans):
        for k, i in enumerate(inputs):
            if (n + k) % 3 == 0:
                plc[f"%I0.{i}"] = (n // 3 + k) % 2
        plc.scan()
    plc.unforce()
    plc.scan()


SHIPPED = sorted((ROOT / "ladder_programs").glob("*.il"))


@pytest.mark.parametrize("il", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_programs_keep_bits_as_bools(il: Path) -> None:
    with PLC.from_file(il, config_for(il), devices=True) as plc:
        assert not non_bools(plc.mem), "before the first scan"
        exercise(plc)
        assert not non_bools(plc.mem)


BLOCKS_PROGRAM = """\
LD 1
ST %M0
LDN 1
ST %M1
LD %MW0:X3
ST %M2
LD %TM0.Q
ST %M3
LD %C0.D
OR %C0.F
ST %M4
LD %I0.0
IN %TM0
CU %C0
LD %I0.1
S %M5
R %M6
LDR %I0.0
XOR %C0.E
ST %Q0.2
LD %SBR0.J1
ST %M7
LD %I0.0
U %DR0
CU %SBR0
CU %SC0
LD %SC0.1
ST %M8
LD 1
[ %MW2 := SHL(%MW1, 1) ]
LD %S17
ST %M9
LD 1
[ %M30:4 := %MW0 ]
[ %MW4 := %MW5 + 32767 ]
LD %S18
ST %M10
"""
BLOCKS_CONFIG = {"timers": {"%TM0": {"type": "TON", "base": "1ms", "preset": 2}},
                 "counters": {"%C0": {"preset": 2}},
                 "drums": {"%DR0": {"steps": [5, 2], "outputs": ["%Q0.5", "%M20", "%M21"]}}}


def test_every_writer_of_the_generated_code_stores_bools() -> None:
    """Constants, word bits, block outputs, S/R, edges, drum outputs, %S17, %S18, bit
    strings, the shift
    register and step counter bits: all land in the images as bools."""
    plc = PLC.from_source(BLOCKS_PROGRAM, BLOCKS_CONFIG)
    plc["%MW0"] = 8
    plc["%MW1"] = -1
    plc["%MW5"] = 1
    exercise(plc, scans=12)
    assert not non_bools(plc.mem)
    assert plc["%M0"] == 1 and plc["%M1"] == 0 and plc["%M2"] == 1 and plc["%M9"] == 1
    assert plc["%M10"] == 1 and plc.mem.m[30:34] == [False, False, False, True]
    assert plc.mem.m[20] != plc.mem.m[21]  # the drum's step (5 or 2) went out


def test_a_bit_read_by_the_user_is_0_or_1() -> None:
    plc = PLC.from_source("LD %I0.0\nST %M0\n")
    plc["%I0.0"] = 1
    plc.scan()
    v = plc["%M0"]
    assert isinstance(v, int) and v == 1 and plc.mem.m[0] is True
    assert plc["%M1"] == 0 and isinstance(plc["%M1"], int)


def test_snapshot_state_file_and_modbus_writes_keep_bools() -> None:
    plc = PLC.from_source("LD %M3\nST %Q0.0\n")
    plc["%M3"] = 1
    plc.scan()
    snap = plc.mem.snapshot()
    plc["%M3"] = 0
    plc.mem.restore(snap)
    assert plc.mem.m[3] is True and not non_bools(plc.mem)
    state = retain.capture(plc.mem)
    plc.mem.m[:] = [False] * len(plc.mem.m)
    retain.apply(plc.mem, state)
    assert plc.mem.m[3] is True and not non_bools(plc.mem)
    image = ModbusImage(plc.mem)
    image.queue_coils(10, bytes([1, 0, 1]))
    assert image.apply_writes() == 1
    assert plc.mem.m[10:13] == [True, False, True] and not non_bools(plc.mem)
