"""Issue 21, runtime side: the state file, the trace and scan timing under attack.

Each test fails on the code before the fix: a replaced or deleted state file lost every
acknowledged write, a full disk under `--trace` killed the daemon, late scan starts were
invisible to the program."""

from __future__ import annotations

import io
import logging
import os
import shutil
import struct
import time
from pathlib import Path

import pytest
from daemon_util import started
from waits import WAIT_S, until

from softplc.daemon import Daemon as InProcessDaemon
from softplc.daemon import DaemonOptions
from softplc.errors import ConfigError
from softplc.machines.drawing.trace import TraceError
from softplc.modbus.image import ModbusImage
from softplc.modbus.rawclient import ModbusExceptionReply
from softplc.persist import retain
from softplc.persist.keeper import StateKeeper
from softplc.persist.retain import StateFileError, StateStore
from softplc.plc import PLC
from softplc.runtime.memory import MemoryImage

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "ladder_programs"
COUNTER = "LD 1\n[ %MW12 := %MW12 + 1 ]\nEND\n"  # %MW12 counts scans


# -- the trace on a full disk -----------------------------------------------------------------
def drawing_table() -> PLC:
    return PLC.from_file(TABLE / "drawing_table.il", config=TABLE / "drawing_table.toml")


def trace_of(plc: PLC):
    return next(d for d in plc.devices.values() if d.type_name == "trace")


def test_trace_on_a_full_disk_stops_the_file_not_the_plc(tmp_path, caplog):
    plc = drawing_table()
    tr = trace_of(plc)
    csv = tmp_path / "t.csv"
    tr.record_to(csv)
    plc.run(1.5)  # simulated seconds: flushed at 1 s
    written = csv.read_text()
    csv.unlink()
    csv.symlink_to("/dev/full")  # every later write: ENOSPC, as on a full disk
    with caplog.at_level(logging.ERROR):
        plc.run(3.0)  # three more flushes due
    assert plc.state == "RUN" and plc.stats.scans == 4500
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(errors) == 1 and "No space left on device" in errors[0].getMessage()
    assert "trace file stops here" in errors[0].getMessage()
    assert tr.file_error.endswith("No space left on device")
    tr.close()  # at shutdown: nothing more tried, no exception
    assert written.startswith("t,x,z,pen,missed\n")


def test_trace_to_dev_full_is_an_error_at_start():
    tr = trace_of(drawing_table())
    with pytest.raises(TraceError, match=r"trace file /dev/full: cannot write: No space left"):
        tr.record_to("/dev/full")


def test_daemon_trace_dev_full_is_a_clear_error(daemons, tmp_path):
    d = started(daemons, tmp_path, "--config", str(TABLE / "drawing_table.toml"), "--trace",
                "/dev/full", program=TABLE / "drawing_table.il", wait=False)
    assert d.proc.wait(WAIT_S) == 1
    err = d.stderr()
    assert "Traceback" not in err
    assert "trace file /dev/full: cannot write: No space left on device" in err


def test_daemon_keeps_running_when_the_trace_disk_fills(daemons, tmp_path):
    csv = tmp_path / "t.csv"
    d = started(daemons, tmp_path, "--config", str(TABLE / "drawing_table.toml"), "--trace",
                str(csv), program=TABLE / "drawing_table.il")
    until(lambda: csv.exists() and csv.stat().st_size > 0)
    full = tmp_path / "full"
    full.symlink_to("/dev/full")
    # in one rename (an unlink then a symlink raced the daemon's next flush, which made the
    # file again in between on a loaded machine): the next flush hits ENOSPC
    full.replace(csv)
    err = d.stderr_until("trace file stops here", 15)
    time.sleep(1.2)  # past the next flush time: not tried again
    assert d.proc.poll() is None  # still running
    with d.client() as c:  # and serving
        n = c.read_registers(0, 1)
        assert len(n) == 1
    assert d.stop() == 0
    err = d.stderr()
    assert "Traceback" not in err
    assert err.count("trace file stops here") == 1 and "No space left on device" in err


# -- scan timing the program sees -------------------------------------------------------------
SEES_OVERRUNS = """\
LD %S19
[ %MW1 := %MW1 + 1 ]
R %S19
LD 1
[ %MW2 := %SW33 ]
[ %MW3 := %SW34 ]
END
"""


class FakeTime:
    """The daemon loop's clock: sleeps return on time except where `late[scan]` (seconds)
    is added, before the scan after `scan` scans."""

    def __init__(self, plc: PLC, late: dict[int, float]):
        self.t = 1000.0
        self.plc = plc
        self.late = late

    def clock(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += seconds + self.late.pop(self.plc.stats.scans, 0.0)


def test_late_and_skipped_starts_are_overruns_the_program_sees():
    plc = PLC.from_source(SEES_OVERRUNS, clock="real")
    out = io.StringIO()
    opts = DaemonOptions(port=0, period=0.010, stats_interval=0.05, rt_priority=0)
    daemon = InProcessDaemon(plc, opts, out=out)
    fake = FakeTime(plc, {5: 0.035})  # the 6th scan starts 35 ms late: 2 starts skipped
    daemon.clock, daemon.sleep = fake.clock, fake.sleep

    def hooks() -> None:
        if plc.stats.scans == 9:  # the 10th scan runs 25 ms (period 10): 1 start skipped
            fake.t += 0.025
        if plc.stats.scans >= 20:
            daemon.request_stop()

    plc.before_scan.append(hooks)
    assert daemon.run() == 0
    w = plc.mem.mw.w
    assert w[1] == 2  # the program saw %S19 after each of the two overruns
    assert (w[2], w[3]) == (1, 3)  # %SW33 late starts, %SW34 skipped starts
    assert (daemon.overruns, daemon.late_starts, daemon.skipped_starts) == (2, 1, 3)
    assert (plc.stats.overruns, plc.stats.late_starts, plc.stats.skipped_starts) == (2, 1, 3)
    text = out.getvalue()
    assert "overruns=2 late=1 skipped=3" in text or "overruns=1 late=1 skipped=2" in text
    assert "2 overruns (1 late starts, 3 starts skipped)" in text


def test_on_time_scans_are_no_overrun():
    plc = PLC.from_source(SEES_OVERRUNS, clock="real")
    daemon = InProcessDaemon(plc, DaemonOptions(port=0, stats_interval=0, rt_priority=0),
                             out=io.StringIO())
    fake = FakeTime(plc, {3: 0.009})  # late, but the cycle still ends within its period
    daemon.clock, daemon.sleep = fake.clock, fake.sleep
    plc.before_scan.append(lambda: plc.stats.scans >= 10 and daemon.request_stop())
    assert daemon.run() == 0
    assert (daemon.overruns, plc.mem.mw.w[1], plc.mem.s[19]) == (0, 0, 0)


# -- the state file deleted, replaced or symlinked --------------------------------------------
def kept_image(path: Path) -> tuple[StateStore, ModbusImage, StateKeeper, list[str]]:
    """A store on `path`, an image writing through it, a keeper (its thread does nothing
    but check, every 0.1 s) and what the keeper told (`on_change`)."""
    mem = MemoryImage()
    store = StateStore.open(path)
    store.start(retain.capture(mem))
    changes: list[str] = []
    keeper = StateKeeper(store, 0, changes.append)
    return store, ModbusImage(mem, store=store, blocks=lambda: b"{}"), keeper, changes


def words(state: retain.RetainedState, n: int) -> tuple[int, ...]:
    return struct.unpack_from(f"<{n}h", state.mw)


@pytest.mark.parametrize("how", ["deleted", "replaced"])
def test_state_file_gone_is_recreated_with_every_acknowledged_write(tmp_path, how):
    path = tmp_path / "plc.state"
    store, img, keeper, changes = kept_image(path)
    try:
        for k in range(100):
            img.write_words(k, [k + 1])
        if how == "deleted":
            path.unlink()
        else:  # another file renamed over it (a restored backup, an editor's save...)
            other = tmp_path / "other"
            other.write_bytes(b"foreign")
            os.replace(other, path)
        for k in range(100, 200):  # acknowledged before the keeper notices
            img.write_words(k, [k + 1])
        until(lambda: keeper.recreated == 1, 5)
        assert not changes  # nothing refused: nothing was lost
        assert store.check() == ""
        with pytest.raises(StateFileError, match="in use by another softplc"):
            StateStore.open(path)  # locked again: a second daemon cannot start on it
        img.write_words(200, [201])
    finally:
        keeper.stop()
        store.close()
    assert words(retain.load(path), 201) == tuple(range(1, 202))


def test_state_file_that_cannot_be_recreated_stops_acknowledging(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    path = folder / "plc.state"
    store, img, keeper, changes = kept_image(path)
    try:
        shutil.rmtree(folder)  # nowhere to re-create it
        until(lambda: bool(changes), 5)
        assert "was deleted" in changes[0] and "cannot be re-created" in changes[0]
        assert not keeper.check()
        folder.mkdir()  # back: re-created at the next check, writes kept again
        until(lambda: len(changes) == 2, 5)
        assert changes[1] == "" and keeper.recreated == 1
    finally:
        keeper.stop()
        store.close()


def test_path_taken_by_another_controller_is_not_overwritten(tmp_path):
    path = tmp_path / "plc.state"
    store, img, keeper, changes = kept_image(path)
    keeper.stop()  # checks by hand
    try:
        img.write_words(0, [7])
        path.unlink()
        other = StateStore.open(path)  # a second daemon started in the meantime
        assert not keeper.check()
        assert "in use by another softplc" in keeper.lost
        other.close()
    finally:
        store.close()


def test_symlinked_state_file_is_refused_unless_asked(tmp_path):
    foreign = tmp_path / "precious.dat"
    foreign.write_bytes(b"not a state file")
    link = tmp_path / "plc.state"
    link.symlink_to(foreign)
    with pytest.raises(StateFileError, match="is a symbolic link .*--state-symlink"):
        StateStore.open(link)
    StateStore.open(link, follow_symlinks=True).close()
    assert foreign.read_bytes() == b"not a state file"  # opening changes nothing


def test_daemon_state_file_deleted_while_running_loses_nothing(daemons, tmp_path):
    state = tmp_path / "plc.state"
    d = started(daemons, tmp_path, "--state", str(state), program=COUNTER)
    with d.client() as c:
        for k in range(100):
            c.write_registers(100 + k, [k + 1])
        state.unlink()
        for k in range(100, 200):
            c.write_registers(100 + k, [k + 1])
        d.wait_for(r"was deleted .* re-created from memory", 5)
        second = started(daemons, tmp_path, "--state", str(state), program=COUNTER,
                         wait=False)
        assert second.proc.wait(WAIT_S) == 1
        assert "in use by another softplc" in second.stderr()
    assert d.stop() == 0
    assert f"state saved to {state}" in d.wait_for("stopped after")
    d = started(daemons, tmp_path, "--state", str(state), program=COUNTER)
    assert "warm start" in "".join(d.out)
    with d.client() as c:
        assert c.read_registers(100, 100) + c.read_registers(200, 100) == list(range(1, 201))
    assert d.stop() == 0


def test_daemon_state_lost_refuses_writes_and_says_not_saved(daemons, tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    state = folder / "plc.state"
    d = started(daemons, tmp_path, "--state", str(state), program=COUNTER)
    with d.client() as c:
        c.write_registers(5, [55])
        shutil.rmtree(folder)
        d.wait_for(r"ERROR: state file .* cannot be re-created", 5)
        with pytest.raises(ModbusExceptionReply):
            c.write_registers(6, [66])
        assert c.read_registers(5, 2) == [55, 0]  # reads still served
    assert d.stop() == 0
    line = d.wait_for("stopped after")
    assert "state NOT saved" in line and "state saved" not in line


def test_daemon_refuses_a_symlinked_state_file(daemons, tmp_path):
    foreign = tmp_path / "precious.dat"
    foreign.write_bytes(b"someone's data")
    (tmp_path / "plc.state").symlink_to(foreign)
    d = started(daemons, tmp_path, "--state", "plc.state", "--cold", program=COUNTER,
                wait=False)
    assert d.proc.wait(WAIT_S) == 1
    err = d.stderr()
    assert "symbolic link" in err and "--state-symlink" in err and "Traceback" not in err
    assert foreign.read_bytes() == b"someone's data"


# -- every numeric setting bounded ------------------------------------------------------------
@pytest.mark.parametrize("raw, message", [
    ({"scan_period": "0.1us"}, "scan_period: a scan period is at least 1 us"),
    ({"scan_period": "2d"}, "scan_period: not a duration"),
    ({"scan_period": "1441min"}, "scan_period: longer than 24 h"),
    ({"watchdog": "0ms"}, "watchdog: the watchdog is at least 1 ms"),
    ({"daemon": {"stats_interval": "1us"}}, "daemon.stats_interval: 0 (off) or at least 10 ms"),
    ({"daemon": {"save_interval": "2ms"}}, "daemon.save_interval: 0 (off) or at least 10 ms"),
    ({"daemon": {"rt_priority": 2**63}}, "daemon.rt_priority: expected less than or equal to 99"),
    ({"drums": {"%DR0": {"steps": [1] * 9}}}, "should have at most 8 items"),
    ({"drums": {"%DR0": {"steps": [70000]}}}, "steps[0]: expected less than or equal to 65535"),
    ({"timers": {"%TM0": {"preset": 2**63}}}, "preset: expected less than or equal to 9999"),
    ({"devices": {"t": {"type": "trace", "max_samples": 2**63}}},
     "max_samples: expected less than or equal to 10000000"),
    # found by tools/fuzz_mutations.py: round(1e308 / scan period) crashed the first scan
    ({"devices": {"o": {"type": "oven", "sensor": "%IW0.0", "heater_bit": "%Q0.0",
                        "dead_time": 1e308}}},
     "devices.o.dead_time: expected less than or equal to 600"),
    ({"devices": {"X": {"type": "servo_axis", "servo_clock_hz": 1e308, "plant": {"K": 1.0}}}},
     "devices.X.servo_clock_hz: expected less than or equal to 50000"),  # crashed a scan
    ({"devices": {"s": {"type": "scope", "axis": "X", "torque_per_bit": 0.01, "seed": -1}}},
     "devices.s.seed: expected greater than or equal to 0"),  # crashed at STORE
    ({"devices": {"s": {"type": "scope", "axis": "X", "torque_per_bit": 0.01,
                        "noise": [0, 0, -1, 0]}}},
     "devices.s.noise[2]: expected greater than or equal to 0"),
    ({"pid": {"0": {"measure": "%MW0", "setpoint": 99999}}},
     "pid.0.setpoint: expected a valid string or less than or equal to 32767"),
    ({"pid": {"0": {"measure": "%MW0", "setpoint": 0, "at_timeout": 1e9}}},
     "pid.0.at_timeout: expected less than or equal to 86400"),
    ({"pid": {"0": {"measure": "%MW0", "setpoint": 0, "measure_span": 2**40}}},
     "pid.0.measure_span: expected less than or equal to 32767"),
])
def test_numeric_settings_are_bounded(raw, message):
    from softplc.errors import ConfigError

    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %M0\n", config=raw)
    assert message in str(e.value)


@pytest.mark.parametrize("flag", ["--stats-interval", "--save-interval"])
def test_interval_flags_are_bounded(daemons, tmp_path, flag):
    d = started(daemons, tmp_path, flag, "1us", program=COUNTER, wait=False)
    assert d.proc.wait(WAIT_S) == 2
    assert "0 (off) or at least 10 ms" in d.stderr()


# -- the garbage collector ---------------------------------------------------------------------
@pytest.mark.parametrize("freeze", [True, False])
def test_start_up_objects_are_frozen_out_of_the_collector(freeze):
    import gc

    plc = PLC.from_source(COUNTER, clock="real")
    daemon = InProcessDaemon(plc, DaemonOptions(port=0, stats_interval=0, rt_priority=0,
                                                gc_freeze=freeze), out=io.StringIO())
    before = gc.get_freeze_count()  # the test worker's own (tests/conftest.py)
    frozen: list[int] = []
    walked: list[bool] = []  # is the PLC among the objects a collection walks?

    def look() -> None:
        frozen.append(gc.get_freeze_count())
        walked.append(any(o is plc for o in gc.get_objects()))
        daemon.request_stop()

    plc.after_scan.append(look)
    assert daemon.run() == 0
    # the program, its image and the servers are frozen while it runs (a full collection
    # then walks none of them); collectable again after
    assert (frozen[0] > before) is freeze
    assert walked[0] is not freeze
    # gc.unfreeze() cannot tell the daemon's objects from the process's own
    assert gc.get_freeze_count() == (0 if freeze else before)


def test_servo_trajectory_of_centuries_is_refused_not_allocated():
    """Found by tools/fuzz_mutations.py: a jog ramp of 1.99e16 ms (Ixx20) asked numpy for
    319 PiB in the first scans. That value is now beyond Ixx20's range (a configuration
    error); the longest ramp in range (8,388,607 ms, 2.3 hours of servo ticks) still makes
    a trajectory too long to hold, and the axis refuses the command (bad command) and holds."""
    import tomllib

    from softplc.devices.axis.law import I24_MAX
    from softplc.devices.axis.options import Err

    cfg = tomllib.loads((TABLE / "cutting_table.toml").read_text())
    cfg["devices"]["X"]["ivars"]["Ixx20"] = 1.9891118211402064e16
    with pytest.raises(ConfigError, match="Ixx20"):
        PLC.from_file(TABLE / "cutting_table.il", config=cfg)
    cfg["devices"]["X"]["ivars"]["Ixx20"] = I24_MAX
    plc = PLC.from_file(TABLE / "cutting_table.il", config=cfg)
    plc.scan(5)
    assert plc.state == "RUN" and plc.devices["X"].error == Err.BAD_COMMAND
