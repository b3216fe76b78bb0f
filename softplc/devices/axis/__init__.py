"""The servo axis device (`type = "servo_axis"`): a PMAC-style position loop, its amplifier
and the mechanics, split by job: `options` (TOML options and the word map), `law` (the
I-variables and the PID + feed-forward law), `plant` (the exact ZOH plant with Coulomb
friction), `trajectory` (S-curve, trapezoid, jog, stop, step, parabolic), `servo` (the
device: commands, servo loop, homing, faults, status words, trace)."""

from .options import Ctl, Err, Mode, St, Word
from .servo import ServoAxis

__all__ = ["Ctl", "Err", "Mode", "ServoAxis", "St", "Word"]
