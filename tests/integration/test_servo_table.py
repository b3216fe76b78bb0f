"""The servo XY table machine end to end: ladder_programs/servo_table.il commanding the two
servo axes (PLC API), and the same over Modbus TCP on loopback with the daemon."""

from __future__ import annotations

import tomllib
from collections.abc import Sequence

import pytest
from daemon_util import ROOT, Daemon
from warm import servo_rows, simulated, warm

from softplc.devices.axis import Err, St
from softplc.modbus.rawclient import ModbusExceptionReply
from softplc.plc import PLC

IL = ROOT / "ladder_programs" / "servo_table.il"
TOML = ROOT / "ladder_programs" / "servo_table.toml"
ESTOP, START, RESET = "%I0.0", "%I0.1", "%I0.2"
AMBER, GREEN, RED, CONTACTOR = "%Q0.0", "%Q0.1", "%Q0.2", "%Q0.3"
X_ST, Y_ST = "%MW218", "%MW248"
REPLY, CELL = "%MW110", "%MW111"
NOT_HOMED, NOT_READY, OUTSIDE, BUSY = -1, -2, -3, -5
HOMING, READY, FAULT, STOPPED = 1, 2, 3, 4


def config(**constants: int) -> dict:
    cfg = tomllib.loads(TOML.read_text())
    cfg["constants"].update(constants)
    return cfg


def new_cell(**constants: int) -> PLC:
    plc = PLC.from_file(IL, config(**constants))
    plc.scan()
    return plc


@pytest.fixture
def cell():
    plc = new_cell()
    yield plc
    plc.close()


@pytest.fixture
def ready():
    """The cell after START, both axes homed, READY: restored to the state of one such
    start in this process (tests/warm.py; test_start_homes_x_then_y checks that it runs
    on as the cell it started does)."""
    plc = warm("servo_table", new_cell, started)
    yield plc
    plc.close()


def press(plc: PLC, button: str) -> None:
    plc[button] = 1
    plc.scan(2)
    plc[button] = 0
    plc.scan()


def request(plc: PLC, req: int, axis: int = 0, target: int = 0, speed: int = 0,
            mode: int = 0) -> int:
    plc["%MW101"], plc["%MD102"], plc["%MD104"] = axis, target, speed
    plc["%MW106"] = plc["%MW107"] = plc["%MW109"] = 0
    plc["%MW108"] = mode
    plc["%MW100"] = req
    plc.scan()
    assert plc["%MW100"] == 0  # handled in one scan
    return plc[REPLY]


def started(plc: PLC) -> None:
    press(plc, START)
    assert plc.run_until(lambda p: p[CELL] == READY, 30.0)


def test_start_homes_x_then_y(cell):
    assert cell[AMBER] and not cell[GREEN] and not cell[CONTACTOR]
    press(cell, START)
    assert cell[CONTACTOR] and cell[GREEN] and not cell[AMBER]
    x, y = cell.devices["X"], cell.devices["Y"]
    order = []
    for _ in range(30000):
        cell.scan()
        for name, st in (("X", X_ST), ("Y", Y_ST)):
            if cell[st] & St.HOMING and name not in order:
                order.append(name)
        if cell[CELL] == READY:
            break
    assert order == ["X", "Y"]
    assert not y.homing and y.homed and x.homed
    assert abs(x.position) <= 10 and abs(y.position) <= 10  # at the index marks
    assert abs(cell["%MD210"]) <= 10 and abs(cell["%MD240"]) <= 10
    # Y started only after X had finished (homed and settled)
    assert cell[X_ST] & St.IN_POSITION and cell[Y_ST] & St.IN_POSITION
    # the `ready` fixture's cell, restored to an earlier start's state, is this one: the
    # same state, and the same after a move of each axis
    restored = warm("servo_table", new_cell, started)
    assert simulated(restored) == simulated(cell)
    k = x.k
    for plc in (cell, restored):
        assert request(plc, 1, 0, -30000, 69632) == 1 and request(plc, 1, 1, -20000) == 1
        plc.run(0.4)
    assert simulated(restored) == simulated(cell)
    rows = servo_rows(cell, k)
    assert len(rows["X"]) > 800 and servo_rows(restored, k) == rows


def test_moves_refused_before_start_and_homing(cell):
    assert request(cell, 1, 0, -1000) == NOT_READY
    press(cell, START)
    assert cell[CELL] == HOMING
    assert request(cell, 1, 0, -1000) == NOT_HOMED
    assert not cell.devices["X"].error  # refused by the program, the axis never saw it


def test_host_move_with_target_checks(ready):
    assert request(ready, 1, 0, 1000) == OUTSIDE  # beyond X max (0)
    assert request(ready, 1, 1, -300000) == OUTSIDE  # beyond Y min
    assert request(ready, 1, 2, -1000) == -4  # no axis 2
    assert request(ready, 1, 1, -20000, 69632) == 1
    assert ready[Y_ST] & St.BUSY
    assert request(ready, 1, 1, -10000) == BUSY
    assert ready.run_until(lambda p: p[Y_ST] & St.DONE, 5.0)
    ready.run(0.3)
    assert abs(ready["%MD240"] + 20000) <= 10
    assert ready["%MW114"] == 5  # requests handled


def test_jammed_axis_fatal_following_error_latches_and_resets(ready):
    ready.devices["X"].set_fault("jammed")
    assert request(ready, 1, 0, -100000, 69632) == 1
    assert ready.run_until(lambda p: p[CELL] == FAULT, 2.0)
    assert ready["%MW112"] == Err.FATAL_FE
    assert ready[X_ST] & St.FE_FATAL and not ready[X_ST] & St.ENABLED
    assert not ready[GREEN]
    assert request(ready, 1, 1, -1000) == NOT_READY  # refused while in fault
    ready.devices["X"].set_fault("none")
    assert request(ready, 3) == 1
    ready.scan(3)
    assert ready[CELL] == READY and ready["%MW112"] == 0 and ready[GREEN]
    assert ready[X_ST] & St.HOMED  # homing stays valid


def test_estop_stops_and_recovery_needs_start_and_reset(ready):
    assert request(ready, 1, 0, -150000, 69632) == 1
    ready.run(0.5)
    x = ready.devices["X"]
    assert x.v < -60000
    ready[ESTOP] = 1
    ready.scan()
    assert ready[RED] and not ready[CONTACTOR] and ready[CELL] == STOPPED
    assert ready.run_until(lambda p: x.v == 0.0, 0.05)  # drives brake at the current limit
    ready.scan(2)
    assert ready[X_ST] & St.AMP_FAULT and not ready[X_ST] & St.ENABLED
    assert not ready[GREEN]
    ready[ESTOP] = 0
    ready.scan(2)
    assert not ready[RED] and ready[AMBER] and ready[CELL] == FAULT
    press(ready, START)
    assert not ready[GREEN]  # amplifier fault still latched
    press(ready, RESET)
    ready.scan(2)
    assert ready[GREEN] and ready[CELL] == READY
    assert request(ready, 1, 0, -1000, 69632) == 1  # no re-homing needed


def test_limit_switch_ends_in_a_fatal_error_with_the_limit_code():
    """A wrong travel constant lets a move run into END-1: the drive refuses torque, the
    PMAC keeps commanding, the warning and then the fatal error follow (spec section 5)."""
    plc = PLC.from_file(IL, config(**{"%KD2": 20000}))
    plc.scan()
    started(plc)
    assert request(plc, 1, 0, 20000, 20000) == 1
    assert plc.run_until(lambda p: p[X_ST] & St.LIMIT_PLUS, 2.0)
    assert plc.run_until(lambda p: p[CELL] == FAULT, 3.0)
    assert plc["%MW112"] == Err.LIMIT
    assert 4096 <= plc.devices["X"].position < 6144
    assert request(plc, 3) == 1
    plc.scan(3)
    assert request(plc, 1, 0, -5000, 20000) == 1  # the way back is allowed
    assert plc.run_until(lambda p: p[X_ST] & St.DONE, 3.0)
    plc.close()


# -- over Modbus, with the daemon ---------------------------------------------------------
def near_home_toml(tmp_path) -> str:
    """The machine with both carriages powered up near home: short homing, quicker tests."""
    text = TOML.read_text()
    for old in ("start = -8000.0", "start = -12000.0"):
        assert old in text
        text = text.replace(old, "start = -2500.0")
    path = tmp_path / "servo_table.toml"
    path.write_text(text)
    return str(path)


def wait(c, pred, reg: int, count: int, timeout: float = 60.0) -> list[int]:
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        regs = c.read_registers(reg, count)
        if pred(regs):
            return regs
        time.sleep(0.01)
    raise AssertionError(f"timeout waiting at %MW{reg}: {regs}")


def s16(v: int) -> int:
    return v - 65536 if v >= 32768 else v


def s32(lo: int, hi: int) -> int:
    v = lo | hi << 16
    return v - (1 << 32) if v >= 1 << 31 else v


def max_fe_counts(out: str) -> float:
    """The max |FE| in counts that `softplc servo` prints."""
    return float(out.split("max |FE| ")[1].split(" counts")[0])


def test_over_modbus_homing_order_refusal_read_only_status_and_servo_command(tmp_path,
                                                                            capsys):
    from softplc.cli import main as softplc

    d = Daemon(tmp_path, "--config", near_home_toml(tmp_path), "--speed", "max",
               "--stats-interval", "0", program=IL)
    try:
        with d.client() as c:
            # status words and the program's replies are read-only for hosts: exception 02
            for addr in (210, 218, 248, 110):
                with pytest.raises(ModbusExceptionReply) as e:
                    c.write_registers(addr, [1])
                assert e.value.code == 2
            # a move before start is refused
            c.write_registers(101, [0, (-1000) & 0xFFFF, 0xFFFF, 0, 0])
            c.write_registers(100, [1])
            wait(c, lambda r: r[0] == 0, 100, 1)
            assert s16(c.read_registers(110, 1)[0]) == NOT_READY
            c.write_registers(100, [5])  # remote start: homes X then Y
            saw_y_before_x_homed = False
            regs = wait(c, lambda r: r[0] & St.HOMING or r[0] & St.HOMED, 218, 1)
            while True:
                x_st, y_st = c.read_registers(218, 1)[0], c.read_registers(248, 1)[0]
                if y_st & St.HOMING and not x_st & St.HOMED:
                    saw_y_before_x_homed = True
                if c.read_registers(111, 1)[0] == READY:
                    break
            assert not saw_y_before_x_homed
            regs = c.read_registers(210, 2) + c.read_registers(240, 2)
            assert abs(s32(*regs[:2])) <= 10 and abs(s32(*regs[2:])) <= 10
            # a move in the travel is accepted and ends in position
            c.write_registers(101, [0, (-20000) & 0xFFFF, 0xFFFF, 69632 & 0xFFFF, 1, 0, 0,
                                    0])
            c.write_registers(100, [1])
            wait(c, lambda r: r[0] == 0, 100, 1)
            assert s16(c.read_registers(110, 1)[0]) == 1
            wait(c, lambda r: r[0] & St.DONE, 218, 1)
            wait(c, lambda r: r[0] & St.IN_POSITION, 218, 1)
            assert abs(s32(*c.read_registers(210, 2)) + 20000) <= 10
            del regs
        # the host command: the thesis's S-curve test on Y, then a refused move
        plot = tmp_path / "scurve.png"
        assert softplc(["servo", "scurve", "--axis", "Y", "--port", str(d.port), "--start",
                        "--from", "-128000", "--plot", str(plot), "--poll", "0.01",
                        "--settle", "0.3"]) == 0
        out = capsys.readouterr().out
        fe = max_fe_counts(out)
        # TABLA 4-3, Y: 11.8 counts. After the approach moves and a rest, the 12-bit DAC,
        # the friction and the integrator hunt at standstill and the stored integral adds
        # to the peak (docs/machines/servo-table.md, "The thesis reproduced"). How long the
        # axis rests depends on the host's polling against the PLC's speed (--speed max):
        # 14.54 counts for a host that answers at once, up to 21.39 for a rest of 1 s or more
        # (test_scurve_fe_depends_on_the_rest_before_the_move), so the band is wider than
        # the device test's (loop closed fresh at rest: 10.2, +-40 %).
        assert 0.6 * 11.8 <= fe <= 1.85 * 11.8
        # the command prints FE to 2 decimals and um (409.6 counts/mm) from the unrounded
        # value: compare within the rounding of both figures
        um = float(out.split("max |FE| ")[1].split(" um")[0].split()[-1].lstrip("("))
        assert abs(um - fe / 409.6 * 1000) <= 0.05 + 0.005 / 409.6 * 1000
        assert " um" in out and plot.stat().st_size > 10_000
        # a move beyond the travel is refused by the program: a clear error, exit 1
        assert softplc(["servo", "step", "--axis", "Y", "--port", str(d.port),
                        "--distance", "500000"]) == 1
        assert "target outside the travel" in capsys.readouterr().err
        assert d.stop() == 0
    finally:
        d.kill()


class _WordsClient:
    """A ModbusHost stand-in on a PLC's words (the holding registers, unsigned on the
    wire), for running the host commands in-process on the virtual clock."""

    def __init__(self, plc: PLC):
        self.uw = plc.mem.mw.uw  # the words' unsigned view (what the Modbus server serves)

    def connect(self) -> _WordsClient:
        return self

    def read_words(self, addr: int, n: int) -> list[int]:
        return [int(v) for v in self.uw[addr:addr + n]]

    def write_words(self, addr: int, values: Sequence[int]) -> None:
        for i, v in enumerate(values):
            self.uw[addr + i] = v

    def close(self) -> None:
        pass


@pytest.mark.parametrize("poll_ms,low,high", [(0, 14.0, 15.0), (100, 17.0, 18.0),
                                              (1000, 21.0, 21.8), (3000, 21.0, 21.8)])
def test_scurve_fe_depends_on_the_rest_before_the_move(tmp_path, monkeypatch, capsys,
                                                       poll_ms, low, high):
    """`softplc servo scurve --from ... --settle 0.3` in-process: each host poll lasts
    `poll_ms` of PLC time (0: one scan), so the axis rests 0.3 s rounded up to a poll
    before the S-curve starts. At standstill the 12-bit DAC, the friction and the
    integrator hunt, and the integral stored at the start adds to the peak FE: 14.54
    counts for a host that answers at once, 21.39 (its limit) after 1 s or more. Over
    Modbus at --speed max a 0.01 s wall poll is anywhere in between, hence the wide band
    of test_over_modbus_homing_order_refusal_read_only_status_and_servo_command."""
    import time
    from types import SimpleNamespace

    import softplc.machines.servo.client as servo_client
    from softplc.cli import main as softplc

    plc = PLC.from_file(IL, tomllib.loads(open(near_home_toml(tmp_path)).read()))
    monkeypatch.setattr(servo_client, "ModbusHost", lambda *a, **k: _WordsClient(plc))
    # the client's own `time` only: its sleeps run the PLC, its timeouts stay wall time
    monkeypatch.setattr(servo_client, "time", SimpleNamespace(
        sleep=lambda s: plc.run(max(poll_ms / 1000, plc.scan_period)),
        monotonic=time.monotonic))
    assert softplc(["servo", "scurve", "--axis", "Y", "--port", "1", "--start", "--from",
                    "-128000", "--poll", "0.01", "--settle", "0.3"]) == 0
    out = capsys.readouterr().out
    fe = max_fe_counts(out)
    assert low <= fe <= high


def test_ivar_words_read_and_write_while_running(ready):
    """servo_table.toml maps X's I-variables at %MW300 (Y %MW350): Ixx30 is the %MF at +28
    (the 13th row of IVARS); a write applies at the next scan, a refused one reverts and
    names the I-variable in +0."""
    from softplc.devices.axis import ivars as iv
    from softplc.devices.axis.law import IVARS

    row = [i for i, *_ in IVARS].index("Ixx30")
    kp = f"%MF{300 + iv.FIRST + 2 * row}"
    assert ready[kp] == 7990 and ready["%MW300"] == 0
    ready[kp] = 8000.0
    ready.scan()
    assert ready.devices["X"].gains.kp == 8000 and ready[kp] == 8000 and ready["%MW301"] == 1
    ready[kp] = -5.0  # out of range: refused, the value in force written back
    ready.scan()
    assert ready.devices["X"].gains.kp == 8000 and ready[kp] == 8000 and ready["%MW300"] == 30
    ready["%MF352"] = 120.0  # Y's load disturbance, DAC bits
    ready.scan()
    assert ready.devices["Y"].disturbance == 120.0


def in_process(tmp_path, monkeypatch, poll_ms: float = 0) -> PLC:
    """The servo host commands on a PLC in this process, on its virtual clock."""
    import time
    from types import SimpleNamespace

    import softplc.machines.servo.client as servo_client

    plc = PLC.from_file(IL, tomllib.loads(open(near_home_toml(tmp_path)).read()))
    monkeypatch.setattr(servo_client, "ModbusHost", lambda *a, **k: _WordsClient(plc))
    monkeypatch.setattr(servo_client, "time", SimpleNamespace(
        sleep=lambda s: plc.run(max(poll_ms / 1000, plc.scan_period)),
        monotonic=time.monotonic))
    return plc


def test_servo_set_and_get_ivars_while_running(tmp_path, monkeypatch, capsys):
    from softplc.cli import main as softplc

    plc = in_process(tmp_path, monkeypatch)
    plc.scan()
    assert softplc(["servo", "get", "I130", "I233", "--port", "1"]) == 0
    assert capsys.readouterr().out.split("\n")[:2] == ["I130 = 7990", "I233 = 13454"]
    assert softplc(["servo", "set", "I130=8000", "I233=12000", "--port", "1"]) == 0
    assert plc.devices["X"].gains.kp == 8000 and plc.devices["Y"].gains.ki == 12000
    for bad, why in [("I130=-1", "greater than or equal to 0"), ("I160=1", "configuration"),
                     ("I330=1", "I1xx (motor 1, X) or I2xx"), ("I134=0.5", "integer")]:
        assert softplc(["servo", "set", bad, "--port", "1"]) == 1
        assert why in capsys.readouterr().err
    assert plc.devices["X"].gains.kp == 8000
    assert softplc(["servo", "disturb", "--axis", "Y", "--load", "40", "--port", "1"]) == 0
    plc.scan()
    assert plc.devices["Y"].disturbance == 40.0


def test_the_docs_servo_examples_run_as_printed(tmp_path, monkeypatch, capsys):
    """The servo table page's `softplc servo` lines, then the command's own --help examples (their
    daemon replaced by the in-process PLC): none refused."""
    import re
    import shlex

    from softplc.cli import main as softplc
    from softplc.machines.servo.command import _EXAMPLES

    plc = in_process(tmp_path, monkeypatch)
    from docs_util import page

    section = page("docs/machines/servo-table.md")
    lines = [ln.split("#")[0].strip() for ln in re.findall(r"^softplc servo .*$", section,
                                                           re.M)]
    helps = [ln.strip() for ln in re.findall(r"^  softplc servo .*$", _EXAMPLES, re.M)]
    assert len(lines) >= 6 and len(helps) >= 10
    for line in lines + helps:
        argv = shlex.split(line)[1:]
        if "--plot" in argv:  # (the plots are checked elsewhere: time)
            del argv[argv.index("--plot"):argv.index("--plot") + 2]
        sim = "--sim" in argv or argv[1] == "compare"
        assert softplc(argv + ([] if sim else ["--port", "1"])) == 0, line
        out = capsys.readouterr()
        assert "refused" not in out.err, line
        if argv[1] == "scurve" and "--start" in argv:  # the page's figure
            assert 14 <= max_fe_counts(out.out) <= 22
    assert plc.devices["X"].gains.kp == 8000  # the page's `set` reached the axis


def test_a_value_the_axis_refuses_is_refused_where_it_is_written(cell):
    """%MF328 (X's Ixx30, kp) := -5: the access port (the web monitor, `softplc io set`)
    and the Modbus server refuse it before it is queued, with the axis's own reason (the
    same check as the table's, `ivars.check`); a value it takes is queued as before."""
    from struct import pack

    from softplc.access import AccessError, AccessPort
    from softplc.modbus import ModbusImage
    from softplc.modbus.protocol import process_pdu
    from softplc.modbus.regmap import ExceptionCode
    from softplc.persist.retain import words_to_be
    from softplc.runtime.memory import WordFamily

    port = AccessPort(cell)
    with pytest.raises(AccessError) as e:
        port.write_many([("%MF328", -5)])
    assert e.value.status == 400
    assert str(e.value).startswith("%MF328 := -5 refused: device 'X': Ixx30 (kp) = -5:")
    assert port.pending == 0
    with pytest.raises(AccessError, match="disturbance"):  # Y's load disturbance word
        port.write_many([("%MF352", 1e6)])
    assert port.write_many([("%MF328", 8000.0)]) == ["%MF328"]
    cell.scan()
    assert cell.devices["X"].gains.kp == 8000

    image = ModbusImage(cell.mem)
    for dev in cell.devices.values():
        if dev.word_check is not None:
            image.check_values(dev.word_check.ranges(), dev.word_check.refusal)

    def wire(*floats: float) -> bytes:
        fam = WordFamily(2 * len(floats))
        for i, f in enumerate(floats):
            fam.set_f(2 * i, f)
        return words_to_be(fam.buf)

    def fc16(addr: int, data: bytes) -> bytes:
        return process_pdu(image, pack(">BHHB", 16, addr, len(data) // 2, len(data)) + data)

    assert fc16(328, wire(-5.0)) == bytes((0x90, ExceptionCode.ILLEGAL_DATA_VALUE))
    assert fc16(326, wire(0.0, -5.0)) == bytes((0x90, ExceptionCode.ILLEGAL_DATA_VALUE))
    assert image.pending == 0
    assert fc16(328, wire(7000.0)) == pack(">BHH", 16, 328, 2)
    assert fc16(329, wire(-5.0)) == pack(">BHH", 16, 329, 2)  # no %MF of the table whole
    assert image.pending == 2


@pytest.mark.parametrize("when", ["built", "cold start"])
def test_a_host_write_after_a_cold_start_changes_that_i_variable_only(when):
    """A cold start clears %MW, the I-variable table with it (issue 33: the e2e test saw
    %MW300 = 69). A host's %MF328 (X's kp) landing before the axis's next scan, the first
    scan of a daemon or the one after a cold start, is the only change applied: the other
    I-variables keep their values (they were taken as written 0: kd := 0, Ixx69 := 0
    refused) and nothing is refused."""
    from softplc.modbus import ModbusImage

    plc = PLC.from_file(IL, config())  # its build ends with a cold start
    try:
        image = ModbusImage(plc.mem)
        plc.before_scan.append(image.apply_writes)  # the daemon's first step of a scan
        x = plc.devices["X"]
        if when == "cold start":
            plc.scan(3)
            plc.cold_start()
        before = x.gains
        image.queue_value("MF", 328, before.kp * 2)  # a host's write, waiting for a scan
        plc.scan(3)
        assert x.gains == before.model_copy(update={"kp": before.kp * 2})
        assert plc["%MW300"] == 0 and plc["%MW301"] == 1 and plc["%MF328"] == before.kp * 2
        assert plc["%MF346"] == before.output_limit  # Ixx69, the table's last row
    finally:
        plc.close()
