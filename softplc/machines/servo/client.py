"""Host side of the servo XY table (ladder_programs/servo_table.il) over Modbus TCP: the
request block, the axis status words, and the tuning moves of the thesis's PMACTuningPro
screens (S-curve, step, parabolic, open loop), with samples for plotting.

Samples are polled: each carries the axis's servo cycle counter, so its time is exact even
though the polling interval is not; the max |FE| reported is the device's own servo-rate
FE_MAX word, not the polled samples' maximum.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TextIO

from softplc.devices.axis.options import DEFAULT_SERVO_CLOCK_HZ, Mode, St, Word
from softplc.errors import HostError, SoftPLCError
from softplc.modbus.host import ModbusHost
from softplc.modbus_codec import (
    float_to_words,
    long_to_words,
    signed_word,
    words_to_float,
    words_to_long,
)

REQ_BLOCK = 100  # %MW100.. (servo_table.il header)
REQ_MOVE, REQ_HOME, REQ_RESET, REQ_STOP, REQ_START = 1, 2, 3, 4, 5
REPLY, CELL = 110, 111
CELL_READY = 2
AXIS_BASE = {"X": 200, "Y": 230}
REPLIES = {1: "accepted", -1: "not homed", -2: "cell not started or in fault",
           -3: "target outside the travel", -4: "bad request", -5: "axis busy"}
CELL_STATES = {0: "not started", 1: "homing", 2: "ready", 3: "fault", 4: "E-stop"}


class ServoClientError(SoftPLCError):
    """The table refused a request, did not answer in time, or the connection failed."""


def _d(regs: list[int], i: int) -> int:
    return words_to_long(regs[i], regs[i + 1])


def _f(regs: list[int], i: int) -> float:
    return words_to_float(regs[i], regs[i + 1])


@dataclass
class AxisState:
    actual: int
    commanded: int
    fe: float
    fe_max: float
    status: int
    error: int
    ticks: int
    output: float

    @classmethod
    def decode(cls, regs: list[int]) -> AxisState:
        """From the status words (offsets Word.ACTUAL.. relative to Word.ACTUAL)."""
        o = Word.ACTUAL
        return cls(_d(regs, Word.ACTUAL - o), _d(regs, Word.COMMANDED - o),
                   _f(regs, Word.FE - o), _f(regs, Word.FE_MAX - o), regs[Word.STATUS - o],
                   signed_word(regs[Word.ERROR - o]), _d(regs, Word.TICKS - o),
                   _f(regs, Word.OUTPUT - o))


@dataclass
class TuningResult:
    test: str
    axis: str
    fe_max: float  # counts, at the servo rate (the device's FE_MAX word)
    moved: int  # counts
    duration: float  # s, from the command to DONE
    samples: list[tuple[float, int, int, float, float]] = field(default_factory=list)
    # (t s, commanded, actual, fe, output)


class ServoClient:
    """The servo table's host over the hosts' one Modbus client (`ModbusHost`); its
    failures are ServoClientErrors."""

    def __init__(self, host: str, port: int, *, timeout: float = 2.0,
                 servo_hz: float = DEFAULT_SERVO_CLOCK_HZ, poll: float = 0.002,
                 progress: TextIO | None = None):
        # no retries: a request is sent once (a repeated request pulse is a new request)
        self.c = ModbusHost(host, port, poll_interval=poll, request_timeout=timeout,
                            retries=0)
        try:
            self.c.connect()
        except HostError as e:
            raise ServoClientError(str(e)) from None
        self.servo_hz = servo_hz
        self.poll = poll
        self.progress = progress

    def close(self) -> None:
        self.c.close()

    def __enter__(self) -> ServoClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _say(self, text: str) -> None:
        if self.progress is not None:
            print(text, file=self.progress, flush=True)

    def _read(self, addr: int, n: int) -> list[int]:
        try:
            return self.c.read_words(addr, n)
        except HostError as e:
            raise ServoClientError(str(e)) from None

    def _write(self, addr: int, words: list[int] | tuple[int, ...], what: str) -> None:
        try:
            self.c.write_words(addr, words)
        except HostError as e:
            raise ServoClientError(f"writing {what}: {e}") from None

    def axis(self, name: str) -> AxisState:
        b = AXIS_BASE[name]
        return AxisState.decode(self._read(b + Word.ACTUAL, Word.SIZE - Word.ACTUAL))

    def cell(self) -> int:
        return self._read(CELL, 1)[0]

    def request(self, req: int, axis: str = "X", target: int = 0, speed: int = 0,
                acc_ms: int = 0, scurve_ms: int = 0, mode: int = 0, open_loop: int = 0,
                timeout: float = 5.0) -> int:
        """Write the request block, wait until the program clears REQ; the reply code."""
        block = [0 if axis == "X" else 1, *long_to_words(target), *long_to_words(speed),
                 acc_ms, scurve_ms, mode, open_loop & 0xFFFF]
        self._write(REQ_BLOCK + 1, block, "the request block")
        self._write(REQ_BLOCK, [req], "the request block")
        end = time.monotonic() + timeout
        while self._read(REQ_BLOCK, 1)[0]:
            if time.monotonic() > end:
                raise ServoClientError(f"the PLC did not take request {req} within "
                                       f"{timeout:g} s (is servo_table.il running?)")
            time.sleep(self.poll)
        return signed_word(self._read(REPLY, 1)[0])

    def ensure_ready(self, start: bool, timeout: float = 120.0) -> None:
        state = self.cell()
        if state == CELL_READY:
            return
        if not start or state not in (0, 1):
            raise ServoClientError(f"the cell is not ready: {CELL_STATES.get(state, state)}"
                                   + ("" if start else " (use --start to start and home it)"))
        if state == 0:
            self._say("starting the cell: homing X then Y ...")
            self.request(REQ_START)
        end = time.monotonic() + timeout
        while (state := self.cell()) != CELL_READY:
            if state not in (0, 1) or time.monotonic() > end:
                raise ServoClientError(f"homing did not finish: cell "
                                       f"{CELL_STATES.get(state, state)}")
            time.sleep(0.05)
        self._say("cell ready (both axes homed)")

    def _accepted(self, reply: int) -> None:
        if reply != 1:
            raise ServoClientError(f"request refused: {REPLIES.get(reply, reply)}")

    def move_to(self, axis: str, target: int, speed: int = 0, timeout: float = 60.0,
                settle: float = 0.0) -> None:
        self._accepted(self.request(REQ_MOVE, axis, target, speed))
        self._wait_done(axis, timeout, settle=settle)

    def _wait_done(self, axis: str, timeout: float, samples: list | None = None,
                   settle: float = 0.0) -> AxisState:
        end = time.monotonic() + timeout
        done_at = None
        while True:
            st = self.axis(axis)
            if samples is not None:
                samples.append((st.ticks / self.servo_hz, st.commanded, st.actual, st.fe,
                                st.output))
            if st.error:
                raise ServoClientError(f"axis {axis} error {st.error} (status "
                                       f"{st.status:#06x})")
            if st.status & St.DONE and not st.status & St.BUSY:
                if done_at is None:
                    done_at = st.ticks
                if (st.ticks - done_at) / self.servo_hz >= settle:
                    return st
            if time.monotonic() > end:
                raise ServoClientError(f"axis {axis}: no DONE within {timeout:g} s")
            time.sleep(self.poll)

    def tuning_move(self, test: str, axis: str, distance: int, speed: int, acc_ms: int,
                    scurve_ms: int, move_ms: int, output_pct: float,
                    settle: float = 0.1, timeout: float = 60.0) -> TuningResult:
        """One tuning move from where the axis is, like PMACTuningPro's screens."""
        before = self.axis(axis)
        mode = {"scurve": Mode.SCURVE, "step": Mode.STEP, "parabolic": Mode.PARABOLIC,
                "openloop": Mode.OPEN_LOOP, "trapezoid": Mode.TRAPEZOID}[test]
        target = before.actual + distance
        if mode == Mode.PARABOLIC or mode == Mode.OPEN_LOOP:
            acc_ms = move_ms
        samples: list[tuple[float, int, int, float, float]] = [
            (before.ticks / self.servo_hz, before.commanded, before.actual, before.fe,
             before.output)]
        t0 = time.monotonic()
        self._accepted(self.request(REQ_MOVE, axis, target, speed, acc_ms, scurve_ms, mode,
                                    round(output_pct * 100)))
        after = self._wait_done(axis, timeout, samples, settle)
        return TuningResult(test, axis, after.fe_max, after.actual - before.actual,
                            time.monotonic() - t0, samples)


def plot_tuning(result: TuningResult, out: str, counts_per_mm: float = 409.6) -> None:
    """Commanded and actual position and the following error against time, like the
    tuning tool's screens: two panels sharing the time axis, legends outside."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result.samples
    t0 = s[0][0]
    t = [(r[0] - t0) * 1000 for r in s]
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 6),
                                   gridspec_kw={"height_ratios": [3, 2]})
    open_loop = result.test == "openloop"
    if not open_loop:  # in open loop nothing is commanded: the position word follows
        ax1.plot(t, [r[1] / counts_per_mm for r in s], label="commanded", color="tab:blue")
    ax1.plot(t, [r[2] / counts_per_mm for r in s], label="actual", color="tab:orange",
             linestyle="--")
    ax1.set_ylabel("position (mm)")
    ax1.grid(True, alpha=0.3)
    ax1.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    if open_loop:  # no loop, no following error: show the output instead
        ax2.plot(t, [r[4] for r in s], label="DAC output", color="tab:green")
        ax2.set_ylabel("DAC output (bits, 16-bit scale)")
    else:
        ax2.plot(t, [r[3] for r in s], label="following error", color="tab:red")
        ax2.set_ylabel("following error (counts)")
        sec = ax2.secondary_yaxis("right", functions=(lambda c: c / counts_per_mm * 1000,
                                                      lambda u: u * counts_per_mm / 1000))
        sec.set_ylabel("µm")
    ax2.axhline(0, color="black", linewidth=0.5)
    ax2.set_xlabel("time (ms)")
    ax2.grid(True, alpha=0.3)
    # right of the secondary axis's labels, when there is one
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01 if open_loop else 1.12, 1.0),
               borderaxespad=0)
    moved = f"moved {result.moved:+d} counts ({result.moved / counts_per_mm:+.2f} mm)"
    if open_loop:  # the following error means nothing without a loop
        peak = max((r[4] for r in s), key=abs, default=0.0)
        what = f"output {peak:.0f} bits, {moved}"
    else:
        um = result.fe_max / counts_per_mm * 1000
        what = f"{moved}, max |FE| {result.fe_max:.1f} counts ({um:.1f} µm)"
    fig.suptitle(f"{result.test} move, axis {result.axis}: {what}")
    fig.tight_layout()
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)


# -- I-variables over Modbus (the axes' ivar word tables, servo_table.toml) -------------------
AXIS_IVARS = {"X": 300, "Y": 350}
MOTORS = {"1": "X", "2": "Y"}


def ivar_address(name: str) -> tuple[str, str, int]:
    """"I130" -> ("X", "Ixx30", register of its %MF)."""
    from softplc.devices.axis import ivars as iv
    from softplc.devices.axis.law import IVARS

    key = name.strip()
    if not (key[:1] in "Ii" and key[1:].isdigit() and len(key) == 4 and key[1] in MOTORS):
        raise ServoClientError(f"{name!r}: expected I1xx (motor 1, X) or I2xx (motor 2, Y), "
                               "e.g. I130")
    ivar = iv.resolve("I" + key[2:])[0]
    row = [i for i, *_ in IVARS].index(ivar)
    axis = MOTORS[key[1]]
    return axis, ivar, AXIS_IVARS[axis] + iv.FIRST + 2 * row


def parse_ivars(items: list[str], values: bool) -> list[tuple[str, float]]:
    """["I130=8000", ...] (values) or ["I130", ...], checked against the device's
    bounds before anything is sent: [(name, value or 0.0)]."""
    from softplc.devices.axis import ivars as iv
    from softplc.devices.axis.law import Gains

    if not items:
        raise ServoClientError("name I-variables (I130, or I130=8000 to set)")
    out = []
    for item in items:
        name, sep, text = item.partition("=")
        if sep != ("=" if values else ""):
            raise ServoClientError(f"{item!r}: expected " + ("I130=8000" if values else "I130"))
        ivar = ivar_address(name)[1]
        value = 0.0
        if values:
            try:
                value = float(text)
                iv.check(Gains(), ivar, value)  # the device's bounds, said here in words
            except ValueError:
                raise ServoClientError(f"{item!r}: {text!r} is not a number") from None
            except iv.IVarError as e:
                raise ServoClientError(f"{name}: {e}") from None
        out.append((name.strip(), value))
    return out


def set_disturbance(sc: ServoClient, axis: str, bits: float) -> None:
    """The load disturbance word of `axis` (a step of load torque, DAC bits)."""
    from softplc.devices.axis.ivars import DISTURBANCE

    if not abs(bits) <= 32768:
        raise ServoClientError(f"load {bits:g}: expected DAC bits within +-32768")
    sc._write(AXIS_IVARS[axis] + DISTURBANCE, float_to_words(bits), "the load disturbance")


def get_ivar(sc: ServoClient, name: str) -> float:
    _, _, reg = ivar_address(name)
    return _f(sc._read(reg, 2), 0)


def set_ivar(sc: ServoClient, name: str, value: float, timeout: float = 2.0) -> float:
    """Write one I-variable; wait for the device to apply it (APPLIED moves) or refuse
    it (REFUSED names it). Returns the value in force."""
    from softplc.devices.axis import ivars as iv

    parse_ivars([f"{name}={value!r}"], values=True)
    axis, ivar, reg = ivar_address(name)
    base = AXIS_IVARS[axis]
    applied = sc._read(base + iv.APPLIED, 1)[0]
    old = get_ivar(sc, name)
    words = float_to_words(value)
    if list(words) == sc._read(reg, 2):
        return old  # already in force
    sc._write(reg, words, name)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        refused, now = sc._read(base + iv.REFUSED, 2)
        if refused == int(ivar[3:]) and get_ivar(sc, name) == old:  # written back
            raise ServoClientError(f"{name} = {value:g} refused by the axis")
        if now != applied:
            return get_ivar(sc, name)
        time.sleep(sc.poll)
    raise ServoClientError(f"{name}: not applied within {timeout:g} s (is the daemon "
                           "running servo_table.toml?)")
