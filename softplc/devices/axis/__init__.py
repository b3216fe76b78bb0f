"""The servo axis device (`type = "servo_axis"`): a PMAC-style position loop, its amplifier
and the mechanics, split by job: `options` (TOML options and the word map), `law` (the
I-variables and the PID + feed-forward law), `plant` (the exact ZOH plant with Coulomb
friction), `trajectory` (S-curve, trapezoid, jog, stop, step, parabolic), `servo` (the
device: its state, the scan, faults, snapshots, trace) and its jobs: `motion` (commands,
trajectories, homing), `runner` with `loop` (the generated servo loop, the fixed point,
events), `ivars` (I-variables read and written while running, their word table),
`status` (the status words); `rig` runs axes without a PLC program."""

from softplc.devices.axis.options import Ctl, Err, Mode, St, Word
from softplc.devices.axis.servo import ServoAxis

__all__ = ["Ctl", "Err", "Mode", "ServoAxis", "St", "Word"]
