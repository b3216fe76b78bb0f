"""A four-phase stepper motor driving a leadscrew axis (the drawing table's X and Z).

TOML options, table `[devices.NAME]` with `type = "stepper"`:

- `phases`: list of exactly four distinct `%Q` outputs, the coils of phases
  A, B, C, D in that order, e.g. `["%Q1.0", "%Q1.1", "%Q1.2", "%Q1.3"]`; or
- `step` (instead of `phases`): a `%Q` output driven by a `%PLS`/`%PWM` pulse output (a
  step/direction driver): one full step per pulse, counted through the runtime's pulse
  interface (`softplc/runtime/pulse.py`), not by sampling the output; `direction`
  (optional, with `step`): a `%Q` output, 1 = + (towards the far end), 0 = -; without it
  every pulse is a + step.
- `steps_per_unit` (float > 0, default 111.11): motor steps per drawing unit (cm).
- `travel` (float > 0, default 25.0): axis length in units, home (0) to the far end.
- `start` (float, default 0.0): initial position in units, rounded to the nearest whole
  step. Anything but 0 leaves the carriage away from home, so homing is exercised.
- `max_step_rate` (float > 0, default 1000.0): fastest stepping the motor follows, in
  steps/s; a step commanded less than 1/max_step_rate s after the previous move (half
  that for a half step) is lost. `inf` disables the limit.
- `hard_stop_margin` (float >= 0, default 0.5): mechanical stops sit this many units
  beyond each end, at -margin and travel + margin; a step into a stop is lost. `inf`
  removes the stops.

Model. After each scan the four phase outputs are decoded (A = 1, B = 2, C = 4, D = 8)
into an electrical position in half steps: A=0, AB=1, B=2, BC=3, C=4, CD=5, D=6, DA=7.
This covers wave drive (one phase on), two-phase-on full step (the rotor then rests half
way between the wave positions) and half step. The rotor's electrical position is its
position in half steps mod 8, with position 0 (the home switch) aligned with phase A, so
the Twido convention "phase k on for k = count mod 4" moves the motor +1 step per +1 of
the count: phase index increasing (A->B->C->D->A) is the + direction.

Only a change of the pattern acts. With d the distance from the rotor to the new field
(-3..4 half steps): d = +-1 or +-2 (one position ahead or behind, in half-step or
full-step mode) moves the rotor by d half steps; d = +-3 (a half-step position skipped)
also pulls the rotor along, the field being still less than 90 degrees electrical from it
on that side; d = 4 (the opposite phase) gives no torque in either direction and is a
missed step; an impossible pattern (two opposite phases, three or four phases) is a missed
step; all phases off leaves the rotor free where it is (no move, no torque). A move that
comes too fast or runs into a hard stop is a missed step too. A missed step leaves the
rotor where it was; it is counted in `missed_steps` and recorded in `events`.

With `step`, the pulses since the last update move the rotor as many full steps; those
beyond `max_step_rate` x dt, and those into a hard stop, are missed steps.

Attributes: `position` (motor steps from home, a float on a half step), `position_units`,
`missed_steps` (count of lost steps), `steps_taken` (steps moved, either direction),
`events` (the last 100 missed steps as (t, reason, position)).
"""

from __future__ import annotations

import logging
import math
from collections import deque
from operator import itemgetter
from typing import Any

from pydantic import Field, field_validator, model_validator

from softplc.config import Address, InfFloat, Section
from softplc.devices.base import AxisDevice, Device, register_device
from softplc.errors import ConfigCode
from softplc.runtime.memory import MemoryImage
from softplc.twido import catalog

log = logging.getLogger(__name__)

_OFF, _BAD = -1, -2
# Phase bit pattern (A=1, B=2, C=4, D=8) -> electrical position in half steps.
PATTERN_TO_E = [_BAD] * 16
PATTERN_TO_E[0] = _OFF
for _e, _p in enumerate((1, 3, 2, 6, 4, 12, 8, 9)):
    PATTERN_TO_E[_p] = _e
PHASE_NAMES = "ABCD"
_LOGGED_MISSES = 5  # per device; the rest go to `events` and the counter only
MAX_UNITS = 1e4  # longest travel / margin (units): keeps step counts exact in a float
MAX_STEPS_PER_UNIT = 1e6


def half_steps_to_steps(h: int) -> int | float:
    """A position kept in half steps, as steps: an int on a whole step."""
    return h >> 1 if not h & 1 else h * 0.5


@register_device("stepper")
class Stepper(AxisDevice):
    """A four-phase stepper axis. Internal position: `_h`, in half steps from home."""

    STATE = ("_h", "_last", "_last_move_t", "_taken_h", "missed_steps", "_logged", "_seen")

    class Options(Section):
        phases: list[Address] | None = Field(None, min_length=4, max_length=4)
        step: Address | None = None  # a %PLS/%PWM output: step/direction drive
        direction: Address | None = None
        steps_per_unit: float = Field(111.11, gt=0, le=MAX_STEPS_PER_UNIT, allow_inf_nan=False)
        travel: float = Field(25.0, gt=0, le=MAX_UNITS, allow_inf_nan=False)
        start: float = Field(0.0, ge=-MAX_UNITS, le=MAX_UNITS, allow_inf_nan=False)
        max_step_rate: InfFloat = Field(1000.0, gt=0)
        hard_stop_margin: InfFloat = Field(0.5, ge=0)

        @field_validator("hard_stop_margin")
        @classmethod
        def _finite_or_none(cls, v: float) -> float:
            if not (math.isinf(v) or v <= MAX_UNITS):
                raise ValueError(f"at most {MAX_UNITS:g} units, or inf for no stops")
            return v

        @model_validator(mode="after")
        def _one_step_source(self) -> Stepper.Options:
            if (self.phases is None) == (self.step is None):
                raise ValueError("give phases (four coils) or step (a pulse output), one of them")
            if self.direction is not None and self.step is None:
                raise ValueError("direction goes with step")
            return self

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.phases = list(options.phases or ())
        self.step, self.direction = options.step, options.direction
        self.steps_per_unit = options.steps_per_unit
        self.travel = options.travel
        self.max_step_rate = options.max_step_rate
        margin = options.hard_stop_margin
        start = options.start
        self.travel_steps = self.travel * self.steps_per_unit
        self.hard_stop_margin = margin
        if math.isinf(margin):
            self._lo_h: float = -math.inf
            self._hi_h: float = math.inf
        else:
            self._lo_h = -math.floor(2 * margin * self.steps_per_unit)
            self._hi_h = math.floor(2 * (self.travel + margin) * self.steps_per_unit)
        self._start_h = 2 * round(start * self.steps_per_unit)
        if not self._lo_h <= self._start_h <= self._hi_h:
            raise self.problem("start", f"{start} is beyond the hard stops "
                               f"(-{margin} .. {self.travel + margin} units)")
        # Shortest time per half step, a hair shorter so that stepping exactly at the limit
        # survives float rounding of t.
        self._min_dt_h = 0.5 / self.max_step_rate * (1 - 1e-6)
        self.events: deque[tuple[float, str, int | float]] = deque(maxlen=100)
        self._get_phases: Any = None
        self._q: list[bool] | None = None
        self.reset()

    # -- contract ---------------------------------------------------------------------------
    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._q = mem.q_field
        if self.step is not None:
            self._bind_pulses(mem)
            return
        idx = [self.io_index(mem, a, "Q", f"phases[{k}]") for k, a in enumerate(self.phases)]
        if len(set(idx)) != 4:
            raise self.problem("phases", f"the four phases must be distinct outputs (got "
                               f"{self.phases!r})", ConfigCode.CONFLICT)
        self._get_phases = itemgetter(*idx)

    def _bind_pulses(self, mem: MemoryImage) -> None:
        """Step/direction: the pulse output driving `step` (runtime/pulse.py)."""
        i = self.io_index(mem, self.step, "Q", "step")
        self._gen = mem.pulses.source(i) if mem.pulses is not None else None
        if self._gen is None:
            pulse = [f for f in catalog.FAMILIES.values() if f.pulse_output]
            raise self.problem(
                "step", f"{self.step} is not driven by a configured "
                f"{' or '.join(f'%{f.kind}' for f in pulse)} ({pulse[0].section}."
                f"\"%{pulse[0].kind}0\" drives %Q0.0, %{pulse[0].kind}1 %Q0.1)",
                ConfigCode.ADDRESS)
        self._dir = None if self.direction is None else \
            self.io_index(mem, self.direction, "Q", "direction")
        self.update = self._update_pulses  # type: ignore[method-assign]

    def reset(self) -> None:
        self._h = self._start_h
        self._last: tuple[int, ...] = (0, 0, 0, 0)  # the rotor starts free
        self._last_move_t = -math.inf
        self._taken_h = 0
        self.missed_steps = 0
        self._logged = 0
        self._seen = 0  # pulses of the step output already applied
        self.events.clear()

    def update(self, t: float, dt: float) -> None:
        cur = self._get_phases(self._q)
        if cur != self._last:  # only a change of the phase pattern acts
            self._last = cur
            self._change(t, cur)

    def _update_pulses(self, t: float, dt: float) -> None:
        """Step/direction: one full step per pulse since the last update."""
        total = self._gen.pulses_at(round(t * 1e6))
        n, self._seen = total - self._seen, total
        if n <= 0:
            return  # none, or the generator's count restarted (a cold start)
        sign = -1 if self._dir is not None and not self._q[self._dir] else 1
        ok = n if math.isinf(self.max_step_rate) else \
            min(n, math.floor(self.max_step_rate * dt * (1 + 1e-9)))
        if ok < n:
            self._lose(t, n - ok, f"{n} pulses in {dt:g} s: faster than "
                                  f"{self.max_step_rate:g} steps/s")
        nh = self._h + 2 * sign * ok
        stop = min(max(nh, self._lo_h), self._hi_h)
        if abs(nh - stop) >= 2:
            self._lose(t, int(abs(nh - stop)) // 2, "hard stop")
        if stop != self._h:
            self._taken_h += abs(stop - self._h)
            self._h = int(stop)
            self._last_move_t = t

    def _lose(self, t: float, n: int, reason: str) -> None:
        """n steps missed at once (one event, one log line)."""
        self._miss(t, reason)
        self.missed_steps += n - 1

    def status(self) -> dict[str, Any]:
        drive = {"pulses": self._seen} if self.step is not None else \
            {"phases": self.pattern_name(self._last)}
        return {"pos": self.position, "units": round(self.position_units, 3),
                "missed": self.missed_steps, **drive}

    def view(self, since_t: float) -> dict[str, Any] | None:
        return {"steps_per_unit": self.steps_per_unit, "travel": self.travel}

    # -- physics ----------------------------------------------------------------------------
    def _change(self, t: float, cur: tuple[int, ...]) -> None:
        a, b, c, d = cur
        e = PATTERN_TO_E[(1 if a else 0) | (2 if b else 0) | (4 if c else 0) | (8 if d else 0)]
        if e < 0:
            if e == _BAD:
                self._miss(t, f"impossible phase pattern {self.pattern_name(cur)}")
            return  # all off: the rotor is free and stays
        h = self._h
        dist = (e - h) & 7  # rotor electrical position is h mod 8
        if dist == 0:
            return
        if dist == 4:
            self._miss(t, f"opposite phase {self.pattern_name(cur)}: no torque")
            return
        if dist > 4:
            dist -= 8
        nh = h + dist
        if nh < self._lo_h or nh > self._hi_h:
            self._miss(t, "hard stop")
            return
        mag = dist if dist > 0 else -dist
        since = t - self._last_move_t
        # (since < 0: the clock was restarted without a reset; do not hold that against it)
        if 0 <= since < mag * self._min_dt_h:
            self._miss(t, f"step faster than {self.max_step_rate:g} steps/s")
            return
        self._h = nh
        self._taken_h += mag
        self._last_move_t = t

    def _miss(self, t: float, reason: str) -> None:
        self.missed_steps += 1
        self.events.append((t, reason, self.position))
        if self._logged < _LOGGED_MISSES:
            self._logged += 1
            more = " (further misses are only counted)" if self._logged == _LOGGED_MISSES else ""
            log.warning("%s: missed step at t=%.6f s, position %s: %s%s",
                        self.name, t, self.position, reason, more)

    # -- views ------------------------------------------------------------------------------
    def axis_position(self) -> float:
        return self._h * 0.5

    def axis_end(self) -> float:
        return math.ceil(2 * self.travel_steps) * 0.5  # the first half step at the end

    def trace_position(self) -> int | float:
        return half_steps_to_steps(self._h)

    def missed(self) -> int:
        return self.missed_steps

    @staticmethod
    def pattern_name(cur: tuple[int, ...]) -> str:
        on = "+".join(PHASE_NAMES[k] for k, v in enumerate(cur) if v)
        return on or "off"

    @property
    def position(self) -> int | float:
        """Motor steps from the home switch position (a float on a half step)."""
        return half_steps_to_steps(self._h)

    @position.setter
    def position(self, steps: float) -> None:
        self._h = round(2 * steps)

    @property
    def position_units(self) -> float:
        return self._h * 0.5 / self.steps_per_unit

    @property
    def steps_taken(self) -> int | float:
        return half_steps_to_steps(self._taken_h)
