"""The host side of the drawing table: stream segments to the PLC over Modbus TCP.

Register map (holding register n = %MWn), as the seed's VB client and PLC program use it:

- the host writes ONE FC16 frame of ten registers from address 0:
  `X, Z, 20, 120, 40, Y, 60, 70, 85, 95` - %MW0/%MW1 the segment end in steps, %MW3 = 120
  (INICIO > 100 starts the segment), %MW5 the pen (1 down, 0 up); the other words are the
  seed's fillers, kept so the frame is byte-for-byte the seed's;
- the PLC clears %MW3 when it accepts the segment and sets %MW10 (EJECUTANDO) to 100 while
  moving (in the scan that accepts), 0 once both axes arrived.

Per segment: wait until idle (%MW3 == 0 and %MW10 == 0), send the frame, wait until
accepted (%MW3 == 0), wait until arrived (%MW10 == 0). State is polled with FC3 on
%MW0-%MW14; a nonzero %MW11 (the corrected program's fault code) stops the run.
Communication failures are retried (reconnecting); each wait has its own
timeout; every failure becomes a `HostError` naming the segment and its G-code line.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TextIO

from softplc.errors import HostError
from softplc.machines.gcode.parser import StepSegment
from softplc.modbus.host import ModbusHost, ProgressLine

__all__ = ["DrawClient", "HostError", "StreamResult", "make_frame"]

#: Words 2..9 of the seed's frame, with INICIO (120) at index 3 and the pen at index 5.
FRAME_TEMPLATE = (0, 0, 20, 120, 40, 0, 60, 70, 85, 95)
REG_X, REG_Z, REG_START, REG_PEN, REG_BUSY = 0, 1, 3, 5, 10
#: %MW11: fault code of the corrected program (always 0 with the seed's).
REG_FAULT = 11
FAULTS = {1: "homing timeout: a home switch is broken",
          2: "far-end limit switch hit"}
START_VALUE = 120
POLL_COUNT = 15  # %MW0-%MW14, as the seed reads


def make_frame(x: int, z: int, pen_down: bool) -> list[int]:
    """The ten registers of one segment, from %MW0."""
    for name, v in (("X", x), ("Z", z)):
        if not 0 <= v <= 32767:
            raise HostError(f"{name} = {v} steps does not fit a %MW register (0..32767)")
    frame = list(FRAME_TEMPLATE)
    frame[REG_X], frame[REG_Z], frame[REG_PEN] = x, z, 1 if pen_down else 0
    return frame


@dataclass
class StreamResult:
    """What `DrawClient.stream` did. `next_number` is where `--start-at` resumes."""

    sent: int  # program segments completed in this run
    last_number: int  # number of the last completed program segment (0: none)
    next_number: int
    total: int
    interrupted: bool = False
    point: tuple[int, int] | None = None  # where the pen stopped, in steps


def _mmss(seconds: float) -> str:
    m, sec = divmod(int(round(seconds)), 60)
    return f"{m // 60}:{m % 60:02d}:{sec:02d}" if m >= 60 else f"{m}:{sec:02d}"


class ProgressBar(ProgressLine):
    """A one-line text progress bar (carriage return updates) on a text stream, with the
    elapsed time and an estimate of the time left (from the pace since the first update)."""

    def __init__(self, total: int, stream: TextIO | None = sys.stderr, width: int = 30,
                 clock: Callable[[], float] = time.monotonic):
        super().__init__(stream, width, clock)
        self.total = max(total, 1)
        self.clock = clock
        self._t0 = clock()
        self._done0: int | None = None  # segments already done at the first update (resume)

    def timing(self, done: int) -> str:
        """'0:12 elapsed, ETA 1:05' (ETA once a segment has been timed)."""
        elapsed = self.clock() - self._t0
        if self._done0 is None:
            self._done0 = done
        text = f"{_mmss(elapsed)} elapsed"
        if done > self._done0 and done < self.total:
            left = elapsed / (done - self._done0) * (self.total - done)
            text += f", ETA {_mmss(left)}"
        return text

    def update(self, done: int, seg: StepSegment | None = None) -> None:
        where = f" line {seg.line} ({seg.kind}, pen {'down' if seg.pen_down else 'up'})" \
            if seg else ""
        self.show(done / self.total, f"{done}/{self.total} {self.timing(done)}{where}")


class DrawClient(ModbusHost):
    """A Modbus TCP client that feeds segments to the drawing-table PLC.

    Use as a context manager (connects on enter) or call `connect()` / `close()`.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 5020, *, device_id: int = 1,
                 poll_interval: float = 0.05, request_timeout: float = 1.0,
                 retries: int = 3, idle_timeout: float = 60.0, accept_timeout: float = 5.0,
                 move_timeout: float = 120.0, progress: TextIO | None = sys.stderr,
                 on_segment: Callable[[StepSegment], None] | None = None):
        super().__init__(host, port, device_id=device_id, poll_interval=poll_interval,
                         request_timeout=request_timeout, retries=retries)
        self.idle_timeout = idle_timeout
        self.accept_timeout = accept_timeout
        self.move_timeout = move_timeout
        self.progress = progress
        self.on_segment = on_segment  # called before each program segment is sent
        self.frames_sent = 0

    # -- registers ---------------------------------------------------------------------
    def read_state(self) -> list[int]:
        """%MW0-%MW14 (FC3)."""
        return self.read_words(0, POLL_COUNT)

    def write_frame(self, x: int, z: int, pen_down: bool) -> None:
        """Send one segment: ten registers from %MW0 in one FC16 request."""
        self.write_words(0, make_frame(x, z, pen_down))
        self.frames_sent += 1

    def wait_for(self, ready: Callable[[list[int]], bool], timeout: float,
                 what: str) -> list[int]:
        """Poll until `ready(registers)`; HostError after `timeout` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            regs = self.read_state()
            fault = regs[REG_FAULT]
            if fault:
                raise HostError(f"{what}: the PLC reports fault {fault} in %MW11 "
                                f"({FAULTS.get(fault, 'unknown fault')})")
            if ready(regs):
                return regs
            if time.monotonic() >= deadline:
                raise HostError(f"{what}: timed out after {timeout:g} s "
                                f"(%MW3={regs[REG_START]}, %MW10={regs[REG_BUSY]})")
            time.sleep(self.poll_interval)

    @staticmethod
    def _idle(regs: list[int]) -> bool:
        return regs[REG_START] == 0 and regs[REG_BUSY] == 0

    def move(self, x: int, z: int, pen_down: bool, label: str = "segment") -> None:
        """One full handshake: idle, send, accepted, arrived."""
        self.wait_for(self._idle, self.idle_timeout, f"{label}: waiting for the PLC to be idle")
        self.write_frame(x, z, pen_down)
        self.wait_for(lambda r: r[REG_START] == 0, self.accept_timeout,
                      f"{label}: waiting for the PLC to accept it (%MW3 := 0); is it in RUN?")
        self.wait_for(lambda r: r[REG_BUSY] == 0, self.move_timeout,
                      f"{label}: waiting for the move to end (%MW10 = 0)")

    # -- streaming ---------------------------------------------------------------------
    def stream(self, segments: Sequence[StepSegment], start_at: int = 1,
               lift_at_end: bool = True) -> StreamResult:
        """Send `segments` from number `start_at` (1-based) on.

        Before the first one, if the PLC's last target (%MW0/%MW1) is not that segment's
        start, a pen-up travel goes there first (so resuming never draws a stray line).
        Ctrl-C stops cleanly: the move in progress ends, the pen goes up where it is, and
        the result says where to resume.
        """
        total = len(segments)
        if not 1 <= start_at <= max(total, 1):
            raise HostError(f"--start-at {start_at}: the program has {total} segments")
        todo = list(segments[start_at - 1:])
        bar = ProgressBar(total, self.progress)
        done = start_at - 1
        current: StepSegment | None = None
        frames_before = 0
        point: tuple[int, int] | None = None
        pen = False
        try:
            if todo:
                regs = self.wait_for(self._idle, self.idle_timeout,
                                     "before the first segment: waiting for the PLC to be idle")
                point = (regs[REG_X], regs[REG_Z])
                pen = bool(regs[REG_PEN])
                if point != todo[0].start:
                    self.move(*todo[0].start, False,
                              f"travel to the start of segment {todo[0].number}")
                    point, pen = todo[0].start, False
            bar.update(done)
            for seg in todo:
                current, frames_before = seg, self.frames_sent
                if self.on_segment:
                    self.on_segment(seg)
                label = f"segment {seg.number}/{total} (line {seg.line})"
                if seg.kind == "dwell":
                    self.wait_for(self._idle, self.move_timeout, label)
                    time.sleep(seg.dwell)
                else:
                    self.move(*seg.end, seg.pen_down, label)
                    point, pen = seg.end, seg.pen_down
                done = seg.number
                bar.update(done, seg)
            if lift_at_end and pen and point is not None:
                self.move(*point, False, "lifting the pen at the end")
                pen = False
        except KeyboardInterrupt:
            bar.close()
            # If the current segment's frame went out, the PLC draws it before stopping.
            if current is not None and current.number > done and (
                    self.frames_sent > frames_before):
                done = current.number
            point = self._stop(point)
            return StreamResult(done - start_at + 1, done, done + 1, total, True, point)
        finally:
            bar.close()
        return StreamResult(done - start_at + 1, done, done + 1, total, False, point)

    def _stop(self, point: tuple[int, int] | None) -> tuple[int, int] | None:
        """After Ctrl-C: let the current move end, then lift the pen where it stopped."""
        if self.progress:
            self.progress.write("interrupted: finishing the current move and lifting the pen "
                                "(Ctrl-C again to abandon)\n")
        try:
            regs = self.wait_for(self._idle, self.move_timeout, "stopping")
            # The PLC's last target is where the pen now is.
            point = (regs[REG_X], regs[REG_Z])
            self.move(*point, False, "lifting the pen after Ctrl-C")
        except KeyboardInterrupt:
            raise HostError("interrupted twice: stopped without lifting the pen") from None
        return point
