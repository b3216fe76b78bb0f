"""The streaming host client against a fake drawing-table PLC (pymodbus server on 127.0.0.1)."""

from __future__ import annotations

import io
import math
from pathlib import Path

import pytest
from modbus_util import PymodbusThread, refused_port
from pymodbus.simulator import DataType, SimData, SimDevice

from softplc.cli import main
from softplc.machines.drawing import DrawClient, HostError, make_frame
from softplc.machines.gcode import StepSegment, parse_gcode

SAMPLES = Path(__file__).resolve().parents[2] / "ladder_programs" / "samples"


class FakePLC(PymodbusThread):
    """Holding registers %MW0-%MW49 that follow the drawing-table handshake.

    Every FC3 poll counts as one PLC scan: a pending segment (%MW3 > 100) is accepted
    (%MW3 := 0, %MW10 := 100 in the same scan), and %MW10 drops to 0 after `busy_polls`
    scans. `accept=False` makes a PLC that never accepts (stopped).
    """

    def __init__(self, busy_polls: int = 2, accept: bool = True):
        super().__init__()
        self.busy_polls = busy_polls
        self.accept = accept
        self.frames: list[list[int]] = []  # every FC16 request: (address, values...)
        self.segments: list[tuple[int, int, int]] = []  # accepted (x, z, pen)
        self.reads = 0
        self._busy = 0

    async def action(self, fc, start, address, count, regs, values):
        if fc == 16:
            self.frames.append([address, *values])
        elif fc == 3:
            self.reads += 1
            if regs[3] > 100 and self.accept:
                self.segments.append((regs[0], regs[1], regs[5]))
                regs[3] = 0
                regs[10] = 100
                self._busy = self.busy_polls
            elif self._busy:
                self._busy -= 1
                if not self._busy:
                    regs[10] = 0
        return None

    def device(self) -> SimDevice:
        return SimDevice(id=1, simdata=[SimData(0, count=50, values=0,
                                                datatype=DataType.REGISTERS)],
                         action=self.action)


def client(plc: FakePLC, **kw) -> DrawClient:
    opts = dict(poll_interval=0.001, request_timeout=0.5, retries=1, idle_timeout=2.0,
                accept_timeout=1.0, move_timeout=2.0, progress=None)
    opts.update(kw)
    return DrawClient("127.0.0.1", plc.port, **opts)



SQUARE = "G00 X1 Z1 Y0\nY1\nG01 X3\nZ3\nX1\nZ1\nY0\n"


def test_frame_is_the_seeds():
    assert make_frame(111, 222, True) == [111, 222, 20, 120, 40, 1, 60, 70, 85, 95]
    with pytest.raises(HostError):
        make_frame(40000, 0, False)


def test_streams_every_segment_with_the_handshake():
    steps = parse_gcode(SQUARE).steps()
    with FakePLC(busy_polls=3) as plc, client(plc) as c:
        result = c.stream(steps)
    assert not result.interrupted and result.sent == len(steps) == result.last_number
    # One FC16 frame of exactly ten registers from address 0 per segment.
    assert all(len(f) == 11 and f[0] == 0 for f in plc.frames)
    assert [f[1:] for f in plc.frames] == [make_frame(*s.end, s.pen_down) for s in steps]
    assert plc.segments == [(*s.end, int(s.pen_down)) for s in steps]
    assert plc.segments[-1][2] == 0  # ends pen up


def test_lifts_the_pen_at_the_end():
    steps = parse_gcode("X1 Z1\nY1\nX2").steps()
    with FakePLC() as plc, client(plc) as c:
        c.stream(steps)
    assert plc.segments[-1] == (222, 111, 0)
    assert plc.segments[-2] == (222, 111, 1)


def test_progress_bar_on_stderr_stream():
    out = io.StringIO()
    steps = parse_gcode(SQUARE).steps()
    with FakePLC(busy_polls=1) as plc, client(plc, progress=out) as c:
        c.stream(steps)
    text = out.getvalue()
    assert f"{len(steps)}/{len(steps)}" in text and "[" in text and text.endswith("\n")


def test_resume_travels_pen_up_to_the_segment_start():
    steps = parse_gcode(SQUARE).steps()
    with FakePLC() as plc, client(plc) as c:
        result = c.stream(steps, start_at=4)
    first = steps[3]
    # First a pen-up travel to segment 4's start, then segments 4.. as programmed.
    assert plc.segments[0] == (*first.start, 0)
    assert plc.segments[1:] == [(*s.end, int(s.pen_down)) for s in steps[3:]]
    assert result.sent == len(steps) - 3 and result.next_number == len(steps) + 1


def test_bad_start_at():
    steps = parse_gcode(SQUARE).steps()
    with FakePLC() as plc, client(plc) as c, pytest.raises(HostError, match="start-at 99"):
        c.stream(steps, start_at=99)


def test_ctrl_c_lifts_the_pen_where_it_stopped():
    steps = parse_gcode(SQUARE).steps()

    def interrupt(seg: StepSegment) -> None:
        if seg.number == 4:
            raise KeyboardInterrupt

    with FakePLC() as plc, client(plc, on_segment=interrupt) as c:
        result = c.stream(steps)
    assert result.interrupted and result.last_number == 3 and result.next_number == 4
    assert plc.segments[:3] == [(*s.end, int(s.pen_down)) for s in steps[:3]]
    assert plc.segments[3:] == [(*steps[2].end, 0)]  # pen up, no move
    assert result.point == steps[2].end


def test_ctrl_c_while_moving_finishes_the_move_first():
    steps = parse_gcode(SQUARE).steps()
    plc = FakePLC(busy_polls=5)
    polls = {"n": 0}

    with plc:
        c = client(plc)
        real_read = c.read_state

        def read_and_interrupt():
            regs = real_read()
            if regs[10] == 100 and len(plc.segments) == 3:
                polls["n"] += 1
                if polls["n"] == 2:
                    raise KeyboardInterrupt
            return regs

        c.read_state = read_and_interrupt
        with c:
            result = c.stream(steps)
    assert result.interrupted and result.last_number == 3 and result.next_number == 4
    assert plc.segments[3] == (*steps[2].end, 0)


def test_plc_that_never_accepts_times_out_clearly():
    steps = parse_gcode(SQUARE).steps()
    with FakePLC(accept=False) as plc, client(plc, accept_timeout=0.1) as c:
        with pytest.raises(HostError) as e:
            c.stream(steps)
    msg = str(e.value)
    assert "segment 1/" in msg and "line 1" in msg and "accept" in msg and "%MW3=120" in msg


def test_plc_fault_stops_the_run():
    steps = parse_gcode(SQUARE).steps()
    plc = FakePLC()

    async def faulty(fc, start, address, count, regs, values):
        await FakePLC.action(plc, fc, start, address, count, regs, values)
        if len(plc.segments) == 2:
            regs[11] = 2  # far-end switch

    plc.action = faulty
    with plc, client(plc) as c, pytest.raises(HostError, match="fault 2 .*far-end"):
        c.stream(steps)
    assert len(plc.segments) == 2


def test_unreachable_daemon_is_a_clear_error():
    with refused_port() as port, pytest.raises(HostError) as e:
        DrawClient("127.0.0.1", port, request_timeout=0.5, progress=None).connect()
    assert f"127.0.0.1:{port}" in str(e.value) and "daemon" in str(e.value)


def test_cli_unreachable_gives_message_not_traceback(capsys):
    with refused_port() as port:
        rc = main(["draw", str(SAMPLES / "square.gcode"), "--port", str(port),
                   "--request-timeout", "0.5", "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 1 and "cannot reach the PLC" in err and "Traceback" not in err


def test_cli_draws_and_reports_deviation(tmp_path, capsys):
    src = tmp_path / "l.gcode"
    src.write_text("G00 X1 Z1\nY1\nG01 X3 Z2\nY0\n")
    trace = tmp_path / "trace.csv"
    # An earlier run far off the path, which must not count.
    trace.write_text("t,x,z,pen,missed\n0,2000,2000,1,0\n0.05,111,111,0,0\n")
    plc = FakePLC()

    async def action_and_trace(fc, start, address, count, regs, values):
        await FakePLC.action(plc, fc, start, address, count, regs, values)
        if len(plc.segments) == 4 and fc == 3 and not regs[10]:
            # The daemon flushes this run: on the line, but 4.5 steps above it
            # (4.02 steps away) at one sample.
            trace.write_text("t,x,z,pen,missed\n0,2000,2000,1,0\n0.05,111,111,0,0\n"
                             "0.1,111,111,1,0\n0.2,222,171,1,0\n0.3,333,222,1,1\n"
                             "0.4,333,222,0,1\n")

    plc.action = action_and_trace
    with plc:
        rc = main(["draw", str(src), "--port", str(plc.port), "--poll", "0.001",
                   "--no-progress", "--trace", str(trace)])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert plc.segments[-2:] == [(333, 222, 1), (333, 222, 0)]
    assert "max deviation" in out.out and "missed steps: 1" in out.out
    dev = float(out.out.split("max deviation ")[1].split()[0])
    assert dev == pytest.approx(4.5 * 2 / math.sqrt(5), abs=0.01)


def test_reads_mw0_to_mw14():
    with FakePLC() as plc, client(plc) as c:
        regs = c.read_state()
    assert regs == [0] * 15 and plc.reads == 1
