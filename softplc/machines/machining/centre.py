"""The machining centre of seed 000 (ladder_programs/mass_tuning.toml) driven without its
PLC program: the NC macro's moves and scope commands through the device words, the
following error of one move, the retune the drive makes from an applied parameter row, and
the before/after comparison of `softplc tune --compare`.

    mc = MachiningCentre(Path("work"), mass=22699.0)
    before = mc.fe_of_move(Scenario().measurement)
    mc.record(Scenario())                 # IMCal_.dta, IMMea_.dta in work/
    ...                                   # estimate, select the row (softplc.machines.machining)
    mc.apply(result.mp_values())          # the drive retunes the axis at rest
    after = mc.fe_of_move(Scenario().measurement)
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from softplc.config import load_config
from softplc.devices.axis.options import Ctl, Mode, St, Word
from softplc.devices.axis.rig import Rig
from softplc.devices.base import device_types
from softplc.errors import ConfigError
from softplc.machines.examples import example
from softplc.machines.machining.drive_tuning import DriveTuning
from softplc.machines.machining.scope import SW, Scope
from softplc.machines.machining.synth import CAL_JOB, MEAS_JOB, Run, Scenario

MACHINE_TOML = example("mass_tuning.toml")
POSITIONING = (3000.0 / 60000, 1.0)  # the macro's F3000 approach (m/s), at 1 m/s²
AXES = ("servo_axis", "feed_axis")
APPROACH = 0.005  # m: fe_of_move's approach distance


def machine_devices(path: str | Path = MACHINE_TOML
                    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """The machine's devices as the configuration loader checked them (name ->
    `config.DeviceSection`, options typed), and their tables as written (copies, for the
    rig to override). ConfigError naming the file and every wrong key."""
    raw, _, settings = load_config(path, device_types())
    return settings.devices, copy.deepcopy(raw.get("devices", {}))


def configured_mass(devices: dict[str, Any], ratio: float) -> float:
    """The moving mass (kg) without the workpiece: one drive bit is torque_per_bit Nm,
    ratio x that N at the table; K counts/s² per bit at counts_per_mm x 1000 counts/m
    (`devices`: the typed sections, `machine_devices`)."""
    scope = devices["scope"].options
    axis = devices[scope.axis].options
    return scope.torque_per_bit * ratio * axis.counts_per_mm * 1e3 / axis.plant.K


@dataclass(frozen=True)
class MoveFE:
    """Following error of one move: t (s from the move's start), fe (µm)."""

    t: np.ndarray
    fe: np.ndarray

    @property
    def peak(self) -> float:
        return float(np.abs(self.fe).max()) if len(self.fe) else 0.0

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.fe**2))) if len(self.fe) else 0.0


class MachiningCentre:
    """The axis, recorder and drive of the machine TOML on a rig (1 ms scans), with the
    workpiece making the moving mass `mass` kg; `ideal`: the feed axis without its loop."""

    def __init__(self, directory: Path, mass: float, *, ratio: float = 523.5987756,
                 noise: bool = True, ideal: bool = False,
                 config: str | Path = MACHINE_TOML):
        typed, devs = machine_devices(config)
        scope = typed.get("scope")
        scope = scope if scope is not None and scope.type == "scope" else None
        axis = typed.get(scope.options.axis) if scope is not None else None
        if scope is None or axis is None or axis.type not in AXES:
            raise ConfigError(f"{config}: expected a scope device named scope and the "
                              f"servo_axis its `axis` names")
        self.axis_name = scope.options.axis
        ax = devs[self.axis_name]
        self.m0 = configured_mass(typed, ratio)
        if not mass > 0:
            raise ConfigError(f"mass {mass!r} kg: expected a number > 0")
        ax["plant"]["load_mass_ratio"] = max(mass / self.m0 - 1, 0.0)
        ax.pop("load_mass_word", None)
        ax["type"] = "feed_axis" if ideal else "servo_axis"
        ax["trace"], ax["trace_max"] = True, 1_000_000
        devs["scope"]["directory"] = str(directory)
        if not noise:
            devs["scope"]["noise"] = [0.0] * 4
        self.rig = Rig(devs)
        self.axis = self.rig.axes[self.axis_name]
        self.scope = next(d for d in self.rig.devices.values() if isinstance(d, Scope))
        self.drive = next((d for d in self.rig.devices.values() if isinstance(d, DriveTuning)),
                          None)
        self.cpm = self.axis.opt.counts_per_mm
        self.rig.command(self.axis_name, Ctl.ENABLE)
        self.rig.step(5)

    def move(self, target_m: float, feed: float, accel: float) -> None:
        """A trapezoid move to `target_m` at `feed` m/s and `accel` m/s², waited for."""
        rig, name = self.rig, self.axis_name
        speed = feed * 1e3 * self.cpm
        rig.pulse(name, Ctl.EXECUTE, target=round(target_m * 1e3 * self.cpm),
                  speed=round(speed), mode=Mode.TRAPEZOID, acc_ms=round(feed / accel * 1e3))
        w, status = rig.mem.mw.w, rig.base(name) + Word.STATUS  # (read every scan)
        if not rig.run_until(lambda: not w[status] & St.BUSY, 120):
            raise ConfigError("the axis did not finish its move within 120 s")
        if rig.word(name, Word.ERROR):
            raise ConfigError(f"axis error {rig.word(name, Word.ERROR)} during a move")

    def _scope(self, bit: int, job: int = 0) -> None:
        w, b = self.rig.mem.mw.w, self.scope._base
        w[b + SW.JOB], w[b + SW.CONTROL] = job, bit
        self.rig.step()
        w[b + SW.CONTROL] = 0

    def record(self, sc: Scenario) -> None:
        """INERT_MEAS_VS.H's two scope runs (mass-estimation.md §1) with `sc`'s geometry
        and dwells: approach at F3000, dwell, START, dwell, out, dwell Q5, back, dwell,
        STOP, STORE (IMCal_.dta, IMMea_.dta), dwell."""
        for job, run in ((CAL_JOB, sc.calibration), (MEAS_JOB, sc.measurement)):
            self.move(run.start, *POSITIONING)
            self.rig.run(1.5)
            self._scope(SW.START)
            self.rig.run(run.dwell_before)
            self.move(run.end, run.feed, run.accel)
            self.rig.run(run.dwell_between)
            self.move(run.start, run.feed, run.accel)
            self.rig.run(run.dwell_after)
            self._scope(SW.STOP)
            self._scope(SW.STORE, job)
            if self.scope.error:
                raise ConfigError(f"the recorder refused JOB {job} (error {self.scope.error})")
            self.rig.run(1.5)

    def fe_of_move(self, run: Run, settle: float = 0.3) -> MoveFE:
        """The servo-rate following error of `run`'s forward move (start -> end) and
        `settle` s after it, from standstill at its start, approached the same way each
        time (from 5 mm behind, so the friction leaves the same standstill error)."""
        back = run.start - np.sign(run.end - run.start) * APPROACH
        self.move(back, *POSITIONING)
        self.move(run.start, *POSITIONING)
        self.rig.run(0.5)
        n0 = len(self.axis.trace)
        self.move(run.end, run.feed, run.accel)
        self.rig.run(settle)
        rows = np.array(self.axis.trace[n0:], dtype=float).reshape(-1, 4)
        k0 = rows[0, 0] if len(rows) else 0.0
        return MoveFE((rows[:, 0] - k0) * self.axis.T, (rows[:, 1] - rows[:, 2]) / self.cpm * 1e3)

    def apply(self, mps: list[float]) -> None:
        """What the PLC's step 30 does: the 22 MPs into the active words, the count + 1;
        then scans until the drive has retuned the axis (it waits for standstill)."""
        d = self.drive
        if d is None:
            raise ConfigError("the machine has no drive_tuning device")
        mw = self.rig.mem.mw
        base = d.mps_at
        for i, v in enumerate(mps):
            mw.set_f(base + 2 * i, v)
        before = d.applied
        mw.w[d.trigger_at] = (mw.w[d.trigger_at] + 1) & 0x7FFF
        if not self.rig.run_until(lambda: d.applied != before or d.error, 10) or d.error:
            raise ConfigError("the drive did not apply the parameters (error "
                              f"{d.error})")


@dataclass(frozen=True)
class LoadRetune:
    """One load of `compare_loads`: the estimates, the row applied, the FE before/after."""

    load: float  # kg, the simulated moving mass
    mass: float  # kg, estimated on the closed-loop axis (before the retune)
    uncertainty: float
    row: int
    kp_scale: float  # Ixx30 after / before
    before: MoveFE
    after: MoveFE
    mass_retuned: float  # kg, estimated again after the retune
    mass_ideal: float  # kg, estimated on the ideal feed axis (no loop)

    def as_dict(self) -> dict[str, Any]:
        return {"load_kg": self.load, "estimate_kg": self.mass, "uncertainty_kg":
                self.uncertainty, "row": self.row, "kp_scale": self.kp_scale,
                "fe_peak_before_um": self.before.peak, "fe_peak_after_um": self.after.peak,
                "fe_rms_before_um": self.before.rms, "fe_rms_after_um": self.after.rms,
                "estimate_after_retune_kg": self.mass_retuned,
                "estimate_ideal_axis_kg": self.mass_ideal}


def compare_loads(loads: list[float], directory: Path, *, table: str = "machine",
                  geometry: str = "settings", noise: bool = True) -> list[LoadRetune]:
    """Per load: the measurement move's FE with the commissioned gains; the macro's
    recordings, the estimate and the table row; the drive's retune; the same move's FE
    again; and the estimate of the same runs on the retuned and on the ideal axis."""
    from softplc.machines.machining.mpfile import MPFile
    from softplc.machines.machining.params import default_template
    from softplc.machines.machining.recording import read_recording
    from softplc.machines.machining.retune import settings_with_table
    from softplc.machines.machining.synth import macro_scenario, macro_settings
    from softplc.machines.machining.tuning import CAL_FILE, GEOMETRIES, MEAS_FILE, tune

    if geometry not in GEOMETRIES:
        raise ConfigError(f"geometry {geometry!r}: expected one of {', '.join(GEOMETRIES)}")
    macro = geometry == "macro"
    sc = macro_scenario() if macro else Scenario()
    settings = settings_with_table(macro_settings() if macro else None, table)
    template = MPFile(default_template(settings.table.axis))

    def estimate(mc: MachiningCentre, d: Path) -> Any:
        mc.record(sc)
        return tune(settings, read_recording(d / CAL_FILE), read_recording(d / MEAS_FILE),
                    template, None)

    out = []
    for load in loads:
        d = Path(directory) / f"{load:g}kg"
        mc = MachiningCentre(d, load, ratio=settings.ratio, noise=noise)
        kp0 = mc.axis.gains.kp
        before = mc.fe_of_move(sc.measurement)
        res = estimate(mc, d)
        mc.apply(res.mp_values())
        after = mc.fe_of_move(sc.measurement)
        again = estimate(mc, d).estimate.mass
        ideal = MachiningCentre(d / "ideal", load, ratio=settings.ratio, noise=noise,
                                ideal=True)
        out.append(LoadRetune(load, res.estimate.mass, res.estimate.uncertainty,
                              res.row.number, mc.axis.gains.kp / kp0, before, after, again,
                              estimate(ideal, d / "ideal").estimate.mass))
    return out


def markdown_table(results: list[LoadRetune]) -> str:
    """The table of `softplc tune --compare` (docs/machines/machining-centre.md)."""
    rows = ["| load kg | estimate kg (closed loop) | row | Ixx30 x | peak FE before µm "
            "| after µm | RMS FE before µm | after µm | estimate, retuned kg | ideal axis kg |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        def pct(m: float, r: LoadRetune = r) -> str:
            return f"{m:.1f} ({(m / r.load - 1):+.3%})"
        rows.append(f"| {r.load:g} | {pct(r.mass)} ± {r.uncertainty:.1f} | {r.row} "
                    f"| {r.kp_scale:.3f} | {r.before.peak:.2f} | {r.after.peak:.2f} "
                    f"({r.after.peak / r.before.peak - 1:+.0%}) | {r.before.rms:.2f} "
                    f"| {r.after.rms:.2f} | {pct(r.mass_retuned)} | {pct(r.mass_ideal)} |")
    return "\n".join(rows)
