"""The host access port (softplc/access): typed reads, the command queue applied at the scan
boundary (control first, bounded, nothing accepted lost), the status record, the run-state
enum, the Modbus image as its word lane."""

from __future__ import annotations

import json

import pytest

from softplc.access import AccessError, AccessPort, Action, RunState, Status
from softplc.access import commands as C
from softplc.modbus import ModbusImage, ReadOnly
from softplc.plc import PLC
from softplc.runtime.blocks import MAX_VALUE
from softplc.twido.address import parse_address

# a comparison stores a Python bool into the bit list; plain contacts store ints
COMPARE = """\
LD [%MW0 > 3]
ST %M5
LD [%MW0 < 3]
ST %Q0.2
LD %I0.0
ST %Q0.1
LD %MW0:X1
ST %M8
"""
CONFIG = {"timers": {"%TM0": {"base": "10ms", "preset": 5}}}


def plc_of(src: str = COMPARE) -> PLC:
    return PLC.from_source(src + "LD %M0\nIN %TM0\n", config=CONFIG)


def test_reads_are_typed_bits_0_1_whatever_the_code_stored():
    plc = plc_of()
    port = AccessPort(plc)
    plc["%MW0"], plc["%MF10"], plc["%MD20"] = 7, 2.5, -70000
    plc.scan()
    assert plc.mem.m[5] is True  # what the compiled comparison stored
    names = ["%M5", "%Q0.2", "%Q0.1", "%M8", "%MW0", "%MF10", "%MD20", "%TM0", "%TM0.Q",
             "%MW0:X0", "%S6", "%I0.0"]
    refs = [parse_address(n) for n in names]
    fast = port.read_now(refs)
    slow = [port.reading.read_one(r) for r in refs]
    assert fast == slow
    for name, v in zip(names, fast, strict=True):
        if name == "%MF10":
            assert type(v) is float and v == 2.5
        elif name == "%TM0":
            assert all(type(x) is int for k, x in v.items() if k not in ("type", "base"))
        else:
            assert type(v) is int, (name, v)
    assert fast[:4] == [1, 0, 0, 1]  # %M5 (7 > 3), %Q0.2, %Q0.1, %M8 (bit 1 of 7)
    text = json.dumps(dict(zip(names, fast, strict=True)))
    assert "true" not in text and "false" not in text


def test_control_first_then_data_in_order_at_the_boundary():
    plc = plc_of()
    port = AccessPort(plc)
    port.write_many([("%MW3", 5), ("%I0.0", 1)])
    assert port.control("stop") is Action.STOP
    assert plc["%MW3"] == 0 and plc.state == RunState.RUN  # nothing before the boundary
    applied: list[tuple[str, int]] = []
    plc.before_scan.append(lambda: applied.append((str(plc.state), plc["%MW3"])))
    plc.scan()
    assert applied == [("STOP", 5)]  # the STOP and the write, both before the program ran
    assert plc.state == "STOP" and plc.state is RunState.STOP
    port.control("run")
    plc.scan()
    assert plc.state == RunState.RUN and plc["%Q0.1"]  # the input, latched


def test_a_full_queue_refuses_and_keeps_what_it_accepted():
    plc = plc_of()
    port = AccessPort(plc)
    for k in range(C.MAX_PENDING):
        port.write_many([("%MW100", k)])
    with pytest.raises(AccessError, match="try again later") as e:
        port.write_many([("%MW101", 1)])
    assert e.value.status == 503
    with pytest.raises(AccessError, match="at most"):
        port.queue.put([C.Control(Action.STOP)] * (C.MAX_URGENT + 1))
    assert port.pending == C.MAX_PENDING
    plc.scan()
    assert port.pending == 0 and plc["%MW100"] == C.MAX_PENDING - 1 and plc["%MW101"] == 0
    assert port.queue.applied == C.MAX_PENDING


def test_an_unforce_drops_the_forcing_still_queued_and_one_lane_per_put():
    plc = plc_of()
    port = AccessPort(plc)
    port.force("%M0", 1)
    port.unforce("%M0")
    assert port.pending == 1  # the force is gone, the unforce waits
    plc.scan()
    assert plc.forced == {}
    with pytest.raises(ValueError):
        port.queue.put([C.Write(parse_address("%MW1"), 1), C.Control(Action.RUN)])


def test_checks_refuse_with_a_clear_error_and_queue_nothing():
    port = AccessPort(plc_of())
    for obj, value, status, text in [
            ("%KW0", 1, 403, "constant"), ("%TM0.V", 1, 403, "read-only"),
            ("%MW1", 70000, 400, "out of range"), ("%M1", 2, 400, "0 or 1"),
            ("%TM0.P", 10000, 400, "out of range 0..9999"),  # a preset a store clamps
            ("%ZZ1", 1, 400, "unknown object")]:
        with pytest.raises(AccessError, match=text) as e:
            port.write_many([("%MW2", 1), (obj, value)])
        assert e.value.status == status
    with pytest.raises(AccessError, match="one of run, stop"):
        port.control("pause")
    with pytest.raises(AccessError, match="cannot be forced"):
        port.force("%TM0.P", 1)
    assert port.pending == 0
    port.refuse_changes = "read-only front-end"
    with pytest.raises(AccessError, match="read-only front-end"):
        port.control("stop")


def test_status_record():
    plc = plc_of()
    port = AccessPort(plc)
    plc.force("%M0", 1)
    plc.scan()
    st = port.status()
    assert isinstance(st, Status) and st.state is RunState.RUN and st.scans == 1
    assert st.forced == {"%M0": 1} and st.forced_count == 1 and st.pending == 0
    d = st.as_dict()
    assert d["state"] == "RUN" and type(d["state"]) is str and d["web_changes_applied"] == 0
    assert json.loads(json.dumps(d))["forced"] == {"%M0": 1}


def test_modbus_image_is_the_word_lane():
    plc = plc_of()
    image = ModbusImage(plc.mem, ReadOnly(registers=[(200, 210)]))
    plc.before_scan.insert(0, image.apply_writes)
    port = AccessPort(plc, image)
    port.write_many([("%MD20", -70000), ("%MF30", 1.5), ("%M7", 1), ("%MW3", 65535)])
    assert port.pending == 0 and image.pending == 4  # coalesced in the image, not queued
    assert image.read_registers_wire(3, 1) == b"\xff\xff"  # read back before the scan
    with pytest.raises(AccessError, match=r"read-only \(\[modbus\]") as e:
        port.write_many([("%MD209", 1)])  # its second word is read-only
    assert e.value.status == 403
    port.force("%MW205", 3)  # a force overrides the host ranges
    plc.scan()
    assert (plc["%MD20"], plc["%MF30"], plc["%M7"], plc["%MW3"]) == (-70000, 1.5, True, -1)
    assert plc["%MW205"] == 3 and port.status().pending == 0


def test_device_listing_is_typed():
    import tomllib
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "ladder_programs"
    cfg = tomllib.loads((folder / "drawing_table.toml").read_text(encoding="utf-8"))
    plc = PLC.from_file(folder / "drawing_table.il", cfg)
    port = AccessPort(plc, hooks=False)
    kinds = {d.name: d.kind for d in port.machine.devices}
    assert kinds["X"] == "stepper" and all(isinstance(k, str) for k in kinds.values())
    assert port.machine.device_io and set(port.machine.device_io.values()) <= set(kinds)
    assert port.queue.apply not in plc.before_scan  # no hooks: the caller applies


def test_bench_access_reports_its_figures():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
    import bench_access

    res = bench_access.run(objects=10, number=50)
    assert res["objects"] == 10 and all(v > 0 for v in res.values())
    assert "us per read" in bench_access.report(res)


def test_a_block_word_that_is_not_a_clamped_preset_takes_a_whole_word():
    """%VFCi.S0 is an unsigned threshold word: 40000 is a value, not out of range (only
    the presets a store clamps, %TMi.P and %Ci.P, stop at MAX_VALUE, 9999)."""
    port = AccessPort(plc_of())
    assert port.check_value(parse_address("%VFC0.S0"), 40000) == 40000
    assert port.check_value(parse_address("%TM0.P"), MAX_VALUE) == MAX_VALUE
    for ref, value in (("%C0.P", MAX_VALUE + 1), ("%TM0.P", 32767), ("%C0.P", -1)):
        with pytest.raises(AccessError, match=f"out of range 0..{MAX_VALUE}"):
            port.check_value(parse_address(ref), value)


def test_a_host_cannot_write_a_preset_the_program_could_never_store():
    """One range for %Ci.P: the program's store clamps to MAX_VALUE
    (docs/twido.md#function-blocks: presets 0-9999), so the port (web, `softplc io`) and
    the REPL's `set` refuse what is above it, and a Modbus host, which can only reach %MW,
    gets its word clamped by the store."""
    from softplc.debug.session import Session

    src = "LD 1\n[ %C0.P := %MW10 ]\nLD %M0\nCU %C0\n"
    plc = PLC.from_source(src)
    image = ModbusImage(plc.mem)
    plc.before_scan.insert(0, image.apply_writes)
    port = AccessPort(plc, image)
    with pytest.raises(AccessError, match=f"out of range 0..{MAX_VALUE}"):
        port.write_many([("%C0.P", MAX_VALUE + 1)])
    image.queue_registers(10, (20000).to_bytes(2, "big"))  # FC 6/16 on %MW10
    plc.scan()
    assert plc["%MW10"] == 20000 and plc["%C0.P"] == MAX_VALUE
    image.queue_registers(10, (40000).to_bytes(2, "big"))  # a signed word: -25536
    plc.scan()
    assert plc["%C0.P"] == 0
    port.write_many([("%C0.P", MAX_VALUE)])
    plc.scan()
    assert plc["%C0.P"] == 0  # the program's store in the same scan wins, as on the PLC
    session = Session(PLC.from_source(src), None)
    refused = session.execute(f"set %C0.P {MAX_VALUE + 1}")
    assert refused == f"error: %C0.P: {MAX_VALUE + 1} is out of range 0..{MAX_VALUE} " \
        "(a preset the program can hold)"
    assert "queued" in session.execute(f"set %C0.P {MAX_VALUE}")
