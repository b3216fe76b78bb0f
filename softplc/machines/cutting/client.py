"""Stream a piece to the cutting-table PLC over Modbus TCP (`softplc cut PIECE`).

Handshake on the words of `regmap.py` (the PLC program is
ladder_programs/cutting_table.il): wait until the PLC is READY and idle, then for each
segment wait until the mailbox is free (INICIO = 0: the PLC has queued the previous
segment) and write the segment in one FC 16 frame (INICIO = 1 last). The PLC queues one
segment while another runs, so the next segment is there when the current one ends (no
segment waits for the host's next poll); a cut followed by a cut is sent as kind 3
(`regmap.piece_words`: the torch stays lit between them whatever the host's timing);
SEG_DONE counts the completed ones. At the end,
wait until SEG_DONE is the last number and EJECUTANDO = 0. A fault code stops the run
with its meaning. Resume: `start_at` N first moves (torch off) to segment N's start if
the carriage is elsewhere. Ctrl-C sets HOLD (%M101): the PLC stops both axes now, torch
off, drops the queued segment, and the result says where to resume (SEG_DONE + 1).
The connection, retries and polling are
`softplc.modbus.host.ModbusHost`'s (shared with the drawing table's client).
"""

from __future__ import annotations

import csv
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np

from softplc.errors import HostError
from softplc.machines.cutting.motion import split_line
from softplc.machines.cutting.piece import MOVE, Piece, Segment
from softplc.machines.cutting.regmap import (
    EJECUTANDO,
    FAULT,
    FAULTS,
    INICIO,
    KIND_CODE,
    POS_X,
    POS_Y,
    SEG_BASE,
    SEG_DONE,
    SEG_NO_MODULO,
    START_VALUE,
    STATE,
    SegmentWords,
    piece_words,
    seg_no,
    to_um,
)
from softplc.modbus.host import ModbusHost, ProgressLine
from softplc.modbus_codec import signed_word, words_to_long
from softplc.runtime.engine import RUN

READY_STEP = 4
MOVING_STEP = 5
FAULT_STEP = 9
HOLD_COIL = 101
#: operator coils of cutting_table.il: RESET, HOME, jog X+ X- Y+ Y- (in FAULT)
RESET_COIL, HOME_COIL = 102, 103
JOG_COILS = {"X+": 104, "X-": 105, "Y+": 106, "Y-": 107}
#: status coils: the four switches (%M114-%M117), then the E-stop pressed (%M119)
SWITCH_COILS = 114
SWITCH_NAMES = ("SensX_Min", "SensX_Max", "SensY_Min", "SensY_Max")
ESTOP_COIL = 119
#: which jog leaves each switch, and which switch each jog runs into (the PLC refuses a
#: jog into a made switch)
LEAVE_SWITCH = {"SensX_Min": "X+", "SensX_Max": "X-", "SensY_Min": "Y+", "SensY_Max": "Y-"}
JOG_INTO = {"X+": "SensX_Max", "X-": "SensX_Min", "Y+": "SensY_Max", "Y-": "SensY_Min"}
#: %MD130 / %MD132: the work origin in the axes' raw counts (cutting_table.il, internal)
ORIGIN_X = 130
STATE_LEN = ORIGIN_X + 4 - SEG_BASE


@dataclass(frozen=True)
class PlcState:
    inicio: int
    ejecutando: int
    fault: int
    step: int
    pos_um: tuple[int, int]
    seg_done: int
    origin_counts: tuple[int, int]

    @classmethod
    def of(cls, regs: list[int]) -> PlcState:
        def w(i: int) -> int:
            return regs[i - SEG_BASE]

        def d(i: int) -> int:
            return words_to_long(w(i), w(i + 1))

        return cls(signed_word(w(INICIO)), w(EJECUTANDO), w(FAULT), w(STATE), (d(POS_X), d(POS_Y)),
                   w(SEG_DONE), (d(ORIGIN_X), d(ORIGIN_X + 2)))

    def __str__(self) -> str:
        return (f"STATE={self.step}, INICIO={self.inicio}, EJECUTANDO={self.ejecutando}, "
                f"SEG_DONE={self.seg_done}")


class PlcFault(HostError):
    """The PLC reports a fault (%MW110): the axes stopped, torch off."""

    def __init__(self, message: str, state: PlcState):
        super().__init__(message)
        self.state = state


def fault_text(code: int) -> str:
    return f"fault {code} ({FAULTS.get(code, 'unknown fault')})"


@dataclass
class CutResult:
    """What `CutClient.stream` did; `next_number` is where `--start-at` resumes (after
    Ctrl-C, or after a fault: the segment that was running or refused)."""

    done: int  # segments completed in this run
    last_number: int  # last completed segment (0: none)
    next_number: int
    total: int
    interrupted: bool
    pos_mm: tuple[float, float]
    origin_counts: tuple[int, int]
    wall: float
    fault: int = 0  # the PLC's fault code (0: none)
    fault_where: str = ""  # the faulted segment's origin (op[3], line 12)


class Progress(ProgressLine):
    """Bar, segments, ETA (wall seconds: the planned motion time still to go at the rate
    seen so far in this run)."""

    def __init__(self, planned: Sequence[float], stream: TextIO | None):
        super().__init__(stream)
        self.planned = list(planned)
        self.total = sum(self.planned) or 1.0
        self.t0 = time.monotonic()
        self.base = 0.0  # planned time already done before this run (resume)

    def update(self, done: int, seg: Segment | None = None) -> None:
        t_done = sum(self.planned[:done])
        ran = t_done - self.base
        rate = (time.monotonic() - self.t0) / ran if ran > 0 else 1.0
        where = f" {seg.kind} {seg.where}" if seg else ""
        self.show(t_done / self.total, f"{done}/{len(self.planned)} segments, ETA "
                  f"{(self.total - t_done) * rate:.1f} s{where}")


class CutClient(ModbusHost):
    def __init__(self, host: str = "127.0.0.1", port: int = 5020, *,
                 poll_interval: float = 0.01, idle_timeout: float = 60.0,
                 move_timeout: float = 600.0, progress: TextIO | None = sys.stderr,
                 **kw: object):
        super().__init__(host, port, poll_interval=poll_interval, **kw)  # type: ignore[arg-type]
        self.idle_timeout = idle_timeout
        self.move_timeout = move_timeout
        self.progress = progress
        self.frames_sent = 0

    def read_state(self) -> PlcState:
        return PlcState.of(self.read_words(SEG_BASE, STATE_LEN))

    def wait_for(self, ready: object, timeout: float, what: str) -> PlcState:
        def check(s: PlcState) -> None:
            if s.fault:
                raise PlcFault(f"{what}: the PLC reports {fault_text(s.fault)} in "
                               f"%MW{FAULT}; clear the cause, then `softplc cut reset`", s)

        return self.poll(self.read_state, ready, timeout, what, check)  # type: ignore[arg-type]

    def offer(self, words: SegmentWords, label: str) -> PlcState:
        """Write one segment into the mailbox once it is free (the PLC has queued the
        previous one); returns the state read just before."""
        state = self.wait_for(lambda s: s.step in (READY_STEP, MOVING_STEP)
                              and s.inicio != START_VALUE,
                              self.move_timeout, f"{label}: waiting for the PLC to take "
                              "the previous segment")
        self.write_words(SEG_BASE, words.frame())
        self.frames_sent += 1
        return state

    def finish(self, number: int, label: str) -> PlcState:
        """Wait until segment `number` (the last one offered) is done and the PLC idle."""
        return self.wait_for(lambda s: s.seg_done == number and s.inicio != START_VALUE
                             and not s.ejecutando, self.move_timeout,
                             f"{label}: waiting for the segment to end")

    def send(self, words: SegmentWords, label: str) -> PlcState:
        """One segment alone: offer it, wait until it is done."""
        self.offer(words, label)
        return self.finish(words.number, label)

    def stream(self, piece: Piece, start_at: int = 1, seed: bool | str = False) -> CutResult:
        """Cut `piece` from segment `start_at`; `seed`: the thesis's path (seed mode: its
        arc steps and Newton evaluation), to see what the machine then cuts."""
        segs = piece.segments(seed=seed)
        total = len(segs)
        if not 1 <= start_at <= max(total, 1):
            raise HostError(f"--start-at {start_at}: the piece has {total} segments")
        planned = [split_line(s.start, s.end, s.speed, piece.accel).duration + s.dwell
                   for s in segs]
        bar = Progress(planned, self.progress)
        bar.base = sum(planned[:start_at - 1])
        done = start_at - 1
        t0 = time.monotonic()
        interrupted = False
        todo = segs[start_at - 1:]
        numbers = {seg_no(s.number): s.number for s in todo}  # SEG_DONE -> segment

        offered = done

        def count(st: PlcState, show: bool = True) -> None:  # segments done (SEG_DONE)
            nonlocal done
            n = numbers.get(st.seg_done, 0)
            if done < n <= offered:  # (a SEG_DONE left by an earlier run is not ours)
                done = n
                if show:
                    bar.update(done, segs[done - 1])

        fault = 0
        try:
            state = self.wait_for(lambda s: s.step == READY_STEP and not s.ejecutando,
                                  self.idle_timeout, "waiting for the PLC to be READY "
                                  "(homed, no fault)")
            if segs:
                first = segs[start_at - 1]
                want = (to_um(first.start[0]), to_um(first.start[1]))
                if any(abs(a - b) > 1 for a, b in zip(state.pos_um, want, strict=True)):
                    # torch off to the start; a number distinct from N and N-1
                    number = seg_no(first.number + SEG_NO_MODULO // 2)
                    self.send(SegmentWords(*want, first.speed, KIND_CODE[MOVE], number),
                              f"move to the start of segment {first.number}")
            bar.update(done)
            for seg, words in zip(todo, piece_words(segs)[start_at - 1:], strict=True):
                count(self.offer(words,
                                 f"segment {seg.number}/{total} ({seg.where})"))
                offered = seg.number
            if todo:
                last = todo[-1]
                count(self.finish(seg_no(last.number), f"segment {last.number}/{total} "
                                  f"({last.where})"))
        except PlcFault as e:
            if offered < start_at:  # before this run sent anything: nothing to resume
                raise
            fault = e.state.fault
            count(e.state, show=False)
        except KeyboardInterrupt:
            interrupted = True
            bar.close()
            self._hold()
        finally:
            bar.close()
        state = self.read_state()
        if interrupted:  # what the PLC completed before HOLD
            count(state, show=False)
        pos = (state.pos_um[0] / 1000.0, state.pos_um[1] / 1000.0)
        where = segs[done].where if fault and done < total else ""
        return CutResult(done - start_at + 1, done, done + 1, total, interrupted, pos,
                         state.origin_counts, time.monotonic() - t0, fault, where)

    def _hold(self) -> None:
        """After Ctrl-C: HOLD stops the axes now with the torch off; then release HOLD."""
        if self.progress:
            self.progress.write("interrupted: stopping the axes, torch off (HOLD)\n")
        try:
            self.write_bit(HOLD_COIL, True)
            self.wait_for(lambda s: not s.ejecutando, self.idle_timeout, "stopping")
            self.write_words(INICIO, [0])  # a segment offered meanwhile is not to be cut
            self.write_bit(HOLD_COIL, False)
        except KeyboardInterrupt:
            raise HostError("interrupted twice: HOLD may still be set (%M101)") from None

    # -- operator commands (softplc cut reset | home | jog) -----------------------------
    def read_bits(self, index: int, count: int) -> list[bool]:
        """%M<index>.. (coils, FC 1)."""
        rr = self._call(f"reading %M{index}:{count}",
                        lambda c, **kw: c.read_coils(index, count=count, **kw))
        return list(rr.bits[:count])  # type: ignore[attr-defined]

    def made_switches(self) -> list[str]:
        bits = self.read_bits(SWITCH_COILS, len(SWITCH_NAMES))
        return [n for n, b in zip(SWITCH_NAMES, bits, strict=True) if b]

    def why_faulted(self) -> list[str]:
        """What keeps RESET refused: made switches (and the jog that leaves each), the
        E-stop; empty if nothing the PLC checks is wrong (an axis still moving)."""
        out = [f"{n} made (softplc cut jog {LEAVE_SWITCH[n]})" for n in self.made_switches()]
        if self.read_bits(ESTOP_COIL, 1)[0]:
            out.append("the E-stop pressed (%I0.16 open)")
        return out

    def reset(self, settle: float = 0.3) -> PlcState:
        """RESET (%M102) in FAULT; waits for READY (after homing if the PLC was not homed).
        HostError saying why if the PLC refuses it."""
        state = self.read_state()
        if state.step != FAULT_STEP:
            raise HostError(f"nothing to reset: the PLC is not in FAULT ({state})")
        self.write_bit(RESET_COIL, True)
        try:
            self.poll(self.read_state, lambda s: s.step != FAULT_STEP, settle, "RESET")
        except HostError:
            why = self.why_faulted() or ["an axis still moving"]
            raise HostError(f"RESET refused, {fault_text(state.fault)} stays: "
                            f"{'; '.join(why)}") from None
        return self.wait_for(lambda s: s.step == READY_STEP, self.move_timeout,
                             "homing after RESET")

    def home(self) -> PlcState:
        """HOME (%M103): from READY with nothing queued, the PLC homes again (search, zero,
        30 mm retract); waits until it is READY again."""
        state = self.read_state()
        if state.step == FAULT_STEP:
            raise HostError(f"the PLC is in FAULT ({fault_text(state.fault)}): clear the "
                            "cause and `softplc cut reset` first")
        if state.step == READY_STEP:
            if state.ejecutando or state.inicio == START_VALUE:
                raise HostError(f"the PLC is busy with a segment ({state}): HOME waits for "
                                "an idle table")
            self.write_bit(HOME_COIL, True)
            self.wait_for(lambda s: s.step != READY_STEP, self.idle_timeout, "HOME")
        elif state.step == MOVING_STEP:
            raise HostError(f"the table is cutting ({state}): HOME waits for an idle table")
        return self.wait_for(lambda s: s.step == READY_STEP, self.move_timeout, "homing")

    def jog(self, direction: str, mm: float, stall: float = 1.0) -> float:
        """Jog one axis (X+, X-, Y+, Y-) by about `mm` in FAULT (to leave a made switch):
        the jog coil is held until the position has moved `mm`, then released; returns
        the distance moved once the axis stood still (the jog's stop ramp adds to it)."""
        coil = JOG_COILS.get(direction.upper())
        if coil is None:
            raise HostError(f"jog {direction!r}: one of {', '.join(JOG_COILS)}")
        if not (math.isfinite(mm) and mm > 0):
            raise HostError(f"jog distance {mm:g} mm must be a positive number")
        axis = 0 if direction.upper()[0] == "X" else 1
        state = self.read_state()
        if state.step != FAULT_STEP:
            raise HostError(f"jog works in FAULT only (the PLC's jog rungs; STATE="
                            f"{state.step}): cut a move segment to go somewhere")
        ahead = JOG_INTO[direction.upper()]
        if ahead in self.made_switches():  # the PLC's jog rungs refuse: say so at once
            raise HostError(f"jog {direction}: {ahead} is made; the PLC jogs only away "
                            "from it")
        p0 = state.pos_um[axis]
        last = [p0, time.monotonic()]

        def far(s: PlcState) -> bool:
            p = s.pos_um[axis]
            if abs(p - last[0]) > 1:
                last[:] = [p, time.monotonic()]
            elif time.monotonic() - last[1] > stall:
                raise HostError(f"jog {direction}: the axis does not move (into a made "
                                "switch? the PLC refuses that)")
            return abs(p - p0) >= mm * 1000.0

        self.write_bit(coil, True)
        try:
            self.poll(self.read_state, far, self.move_timeout, f"jog {direction}")
        finally:
            self.write_bit(coil, False)
        s = self.poll(self.read_state, lambda s: self._still(s, axis), self.idle_timeout,
                      f"jog {direction}: stopping")
        return abs(s.pos_um[axis] - p0) / 1000.0

    def _still(self, s: PlcState, axis: int) -> bool:
        time.sleep(0.05)
        return self.read_state().pos_um[axis] == s.pos_um[axis]


@dataclass(frozen=True)
class TraceReport:
    samples: int  # torch-on samples checked
    worst: float  # mm from the ideal shape
    at: tuple[float, float]
    end: tuple[float, float]  # last sample, work mm


def trace_deviation(piece: Piece, trace_csv: str | Path, origin_true: tuple[float, float],
                    counts_per_mm: float) -> TraceReport:
    """Torch-on samples of a trace CSV (true positions in counts) against the ideal shape;
    `origin_true` is the work origin in true counts (the axis's `start` + the PLC's origin
    in raw counts)."""
    try:
        with open(trace_csv, newline="") as f:
            rows = list(csv.DictReader(f))
        x = (np.array([float(r["x"]) for r in rows]) - origin_true[0]) / counts_per_mm
        y = (np.array([float(r["z"]) for r in rows]) - origin_true[1]) / counts_per_mm
        lit = np.array([r["pen"] == "1" for r in rows], bool)
    except (OSError, KeyError, ValueError) as e:
        raise HostError(f"cannot read the trace {trace_csv}: {e}") from None
    end = (float(x[-1]), float(y[-1])) if len(x) else (math.nan, math.nan)
    if not lit.any():
        return TraceReport(0, 0.0, (math.nan, math.nan), end)
    d = piece.deviations(x[lit], y[lit])
    i = int(np.argmax(d))
    return TraceReport(int(lit.sum()), float(d[i]), (float(x[lit][i]), float(y[lit][i])), end)


def feed_plc(plc: object, piece: Piece, timeout: float = 600.0,
             seed: bool | str = False) -> int:
    """The same handshake in-process on a `softplc.PLC` (virtual clock, no Modbus): write
    each segment's frame into the words as soon as the mailbox is free (INICIO = 0), then
    run scans until SEG_DONE is the last number and EJECUTANDO = 0. Deterministic (each
    frame lands at a known scan): for tests and the benchmark. Returns the number of
    segments cut; HostError on a fault or a timeout. `seed`: the thesis's path."""
    w = plc.mem.mw.w  # type: ignore[attr-defined]  # the words, read without parsing
    uw = plc.mem.mw.uw  # type: ignore[attr-defined]  # the same, unsigned as on the wire

    def stopped(p: object) -> bool:
        return bool(w[FAULT]) or p.state != RUN  # type: ignore[attr-defined]

    def wait(seg: Segment, cond: Callable[[object], bool], what: str) -> None:
        if not plc.run_until(lambda p: cond(p) or stopped(p),  # type: ignore[attr-defined]
                             timeout=timeout):
            raise HostError(f"segment {seg.number} ({seg.where}): {what} after "
                            f"{timeout:g} simulated s")
        if plc.state != RUN:  # type: ignore[attr-defined]
            raise HostError(f"segment {seg.number} ({seg.where}): the PLC is in "
                            f"{plc.state} ({plc.fault})")  # type: ignore[attr-defined]
        if w[FAULT]:
            raise HostError(f"segment {seg.number} ({seg.where}): the PLC reports fault "
                            f"{w[FAULT]} ({FAULTS.get(w[FAULT], 'unknown fault')})")

    segs = piece.segments(seed=seed)
    for seg, words in zip(segs, piece_words(segs), strict=True):
        wait(seg, lambda p: w[INICIO] != START_VALUE, "the previous segment not taken")
        for i, v in enumerate(words.frame()):
            uw[SEG_BASE + i] = v
    if segs:
        last = seg_no(segs[-1].number)
        wait(segs[-1], lambda p: w[SEG_DONE] == last and not w[EJECUTANDO]
             and w[INICIO] != START_VALUE,
             "not done")
    return len(segs)
