"""An online change and the state file, in one process: once the swap is answered, the
state file names the new program, whenever the daemon stops after it."""

from __future__ import annotations

from softplc.access import AccessPort
from softplc.modbus import ModbusImage
from softplc.persist import retain
from softplc.plc import PLC

OLD = "LD 1\n[ %MW10 := 1 ]\n"
NEW = "LD 1\n[ %MW10 := 2 ]\n"
CONFIG = {"timers": {"%TM0": {"preset": 5}}}


def test_a_stop_cutting_the_swaps_scan_short_keeps_the_new_programs_name(tmp_path):
    """Issue 33 (`test_the_state_file_follows_the_loaded_program` failed under load): the
    swap runs at a scan boundary and is answered at once; a stop arriving during that
    scan cuts it short (`Daemon.request_stop`: the image holds, the scan commits nothing),
    and the state file still named the old program: the restart with the new file was no
    warm start. The swap's boundary is committed with the new program's id."""
    plc = PLC.from_source(OLD, CONFIG, file="old.il")
    port = AccessPort(plc)
    old_app, new_app = port.program.app_id(OLD, None), port.program.app_id(NEW, None)
    store = retain.StateStore.open(tmp_path / "plc.state")
    try:
        store.start(retain.capture(plc.mem, old_app))
        image = ModbusImage(plc.mem, store=store)  # as the daemon wires it
        port.program.image = image
        plc.after_scan.append(image.take_snapshot)
        plc["%MW100"] = 123  # retained data the change carries over
        plc.scan(3)
        plan, names = port.program.plan(NEW, None, "new.il")
        port.call(lambda: port.program.swap(plan, names, plc.program_version, confirm=False,
                                            cold=False, app=new_app))

        def stop_requested() -> None:  # what a stop during this scan does (daemon.py)
            image.hold = True

        plc.before_scan.append(stop_requested)  # after the swap: the access port's hook
        plc.scan()
        assert plc.program_version == 1 and plc.ast.file == "new.il"
        store.persist()  # the daemon's shutdown
    finally:
        store.close()
    again = retain.StateStore.open(tmp_path / "plc.state")
    try:
        state = again.load()
    finally:
        again.close()
    assert state is not None and state.app == new_app
    restarted = PLC.from_source(NEW, CONFIG, file="new.il")
    assert retain.restart(restarted, state, app=new_app)[0] == "warm"
    assert restarted["%MW100"] == 123
