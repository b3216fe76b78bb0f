"""The servo axis as its jobs see it: the state they read and change.

`ServoAxis` (servo.py) holds the state and builds its jobs: `Motion` (motion.py),
`LoopRunner` (runner.py), `IVarTable` (ivars.py) and `StatusWords` (status.py, whose
generated code reads the state by name). They name the axis through this `Protocol`, so
they sit below servo.py: the axis imports its jobs, never the reverse. Units: encoder
counts, servo cycles (k), DAC bits (u, w).
"""

from __future__ import annotations

from collections.abc import Callable
from operator import attrgetter
from typing import Any, Protocol

from softplc.devices.axis.law import Coefficients
from softplc.devices.axis.options import ServoAxisOptions
from softplc.devices.axis.plant import ZOH
from softplc.runtime.memory import MemoryImage


class MotionJob(Protocol):
    """What the loop runner asks of the motion job (motion.Motion)."""

    def kill(self, error: int, latch: bool = True) -> None: ...

    def home_trigger(self, capture: float) -> None: ...


class LoopJob(Protocol):
    """What the I-variable table asks of the loop runner (runner.LoopRunner)."""

    def build(self) -> None: ...

    def cycles(self, n: int, capture: bool = False) -> int: ...


class ServoState(Protocol):
    """The state of one servo axis shared by its jobs (ServoAxis.STATE and its constants)."""

    # the plant and the loop: position, velocity, command, output; constants of build()
    x: float
    v: float
    w: float
    u: float
    k: int
    origin: int
    T: float
    loop_hz: float
    K: float
    a: float
    zoh: ZOH
    u_peak: float
    load_mass_ratio: float
    disturbance: float
    gains: Any  # a law.Gains (made by create_model: no static type)
    coef: Coefficients
    # the loop's terms: commanded/actual positions and velocities, integrator
    fe: float
    fe_max: float
    _cp: float
    _cpp: float
    _cvp: float
    _app: float
    _ie: float
    _ca: float
    _av: float
    _vel: float
    # motion: trajectory, open loop, coasting, homing, limits
    closed: bool
    open_loop: bool
    done: bool
    homed: bool
    homing: int
    latched: bool
    warn: bool
    error: int
    _traj: tuple[float, ...]
    _k0: int
    _tail_v: float
    _active: bool
    _ol_u: float
    _ol_end: int
    _coast: bool
    _limit_stop: bool
    _ctl_prev: int
    _ready: bool
    _start: float
    _enc0: int
    _ideal: bool
    _lp: float
    _lm: float
    _hp: float
    _hm: float
    _lo: float
    _hi: float
    _plo: float
    _phi: float
    _pmac_lim: bool
    _in_pos: float
    _warn_lim: float
    # the fixed point, the DAC, the words and the memory image it is bound to
    _fixed: bool
    _creep: int
    _clamped: bool
    _dac_q: float
    _cur_scale: float
    _hz_us: float
    _mem: MemoryImage | None
    _buf: bytearray
    _base: int
    _ctl_i: int
    _status_at: int
    _st_slow: int
    _mass_word: int | None
    _mass_get: Callable[[int], float]
    _mass_f: float
    _estop_idx: int | None
    _power_idx: int | None
    _i: list[bool]
    _q: list[bool]
    _wired: bool
    _watch: bool
    _ivars_clean: Callable[[], bool]
    _scan: Callable[..., Any] | None  # the generated scan of the common case (loop.py)
    # records: the servo-rate trace and a tuning gather
    trace: list[tuple[int, float, float, float]]
    gather: list[tuple[int, float, float, float, float]] | None
    _rec: Callable[[tuple[int, float, float, float]], None] | None
    _trim_at: int
    _trace_dropped: int

    # The fields behind the properties of LOOP_STATE and SHOWN (below): read where speed
    # counts; assign the property, whose setter drops the caches made from it.
    x_: float
    v_: float
    u_: float
    w_: float
    fe_: float
    fe_max_: float
    _cp_: float
    _cpp_: float
    _cvp_: float
    _app_: float
    _ie_: float
    _clamped_: bool
    closed_: bool
    open_loop_: bool
    homing_: int
    fault_: str
    origin_: int
    _traj_: tuple[float, ...]
    _tail_v_: float
    _ready_: bool
    _coast_: bool
    _vel_: float

    @property
    def opt(self) -> ServoAxisOptions: ...

    @property
    def fault(self) -> str: ...  # "none", "jammed", "estop", "amp_fault"

    @property
    def motion(self) -> MotionJob: ...

    @property
    def runner(self) -> LoopJob: ...

    def _raw(self) -> float: ...

    def amp_ready(self) -> bool: ...

    def estop_active(self) -> bool: ...

    def set_disturbance(self, bits: float) -> None: ...


# -- the caches made from the state, dropped where it changes ----------------------------------
# The generated scan keeps what it made from the state (loop.py, runner.py): the status
# words of an axis at a fixed point (`_rest_words`), the status bits that change only with
# a command (`_st_slow`), and the fixed point itself (`_fixed`: the servo cycles skipped
# while the loop's state is unchanged). So each attribute they are made from is a property
# over a field, `name_`, whose setter drops them: whoever assigns it (a job, a snapshot, a
# test, a REPL user), the next scan computes them again. The generated code reads and
# writes the fields (no property's cost); so does the device's own per-scan code where it
# writes the full status words anyway.
LOOP_STATE = ("x", "v", "u", "fe", "_cp", "_cpp", "_cvp", "_app", "_ie", "_clamped",
              "closed", "open_loop", "homing", "fault", "_traj", "_tail_v",
              "_ready")  # the loop's state and drive state: the fixed point's
SHOWN = ("w", "fe_max", "warn", "done", "homed", "error", "latched", "origin", "_vel",
         "_coast")  # shown by the status words only


def field(name: str) -> str:
    """The field behind the property `name` (what generated code reads and writes)."""
    return name + "_"


def _property(name: str, loop: bool) -> property:
    at = field(name)
    # (setattr, not self.__dict__[at]: measured, writing through __dict__ from reset()
    # made every later attribute access of the generated scan slower, 2.09 -> 2.57 us per
    # jogging update of the cutting table's axis)
    if loop:
        def set_(self: Any, value: Any) -> None:
            setattr(self, at, value)
            self._rest_words, self._st_slow, self._fixed = None, -1, False
    else:
        def set_(self: Any, value: Any) -> None:
            setattr(self, at, value)
            self._rest_words, self._st_slow = None, -1
    return property(attrgetter(at), set_, doc=f"(the field {at}; setting it drops the "
                    "caches made from it)")


def guard(cls: type) -> type:
    """Make the attributes of LOOP_STATE and SHOWN properties of `cls` (a class
    decorator of the servo axis)."""
    for name in LOOP_STATE + SHOWN:
        setattr(cls, name, _property(name, name in LOOP_STATE))
    return cls
