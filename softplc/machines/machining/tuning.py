"""One tuning run, independent of how it was requested (the command line or the PLC's
Modbus request): read the files, estimate, pick the table row, write the parameter macro.

Everything is checked before anything is written; the macro is replaced atomically, so a
refusal leaves the previous parameters untouched.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softplc.errors import MassEstimationError
from softplc.machines.machining.csvrec import read_csv
from softplc.machines.machining.estimator import Estimate, estimate
from softplc.machines.machining.files import write_atomic
from softplc.machines.machining.mpfile import MPFile
from softplc.machines.machining.names import (  # noqa: F401  (this module's API too)
    CAL_FILE,
    GEOMETRIES,
    MEAS_FILE,
    OUTPUT_FILE,
    SETTINGS_FILE,
    TEMPLATE_FILE,
)
from softplc.machines.machining.params import MP_NAMES, MP_Q, Row, default_template
from softplc.machines.machining.recording import read_recording, write_recording
from softplc.machines.machining.settings import (
    Settings,
    format_settings,
    read_settings,
    thesis_settings,
)


@dataclass(frozen=True)
class TuneResult:
    estimate: Estimate
    row: Row
    values: dict[int, float]  # Q number -> value written (Q0 = axis index)
    output: Path | None
    template: dict[int, float] = field(default_factory=dict)  # Q -> the template's value

    def mp_values(self) -> list[float]:
        """The 22 MPs in macro order (MP_NAMES)."""
        return [self.values[MP_Q[n]] for n in MP_NAMES]

    def summary(self) -> str:
        e = self.estimate
        kg, x = unit(e), "rad" if e.measurement.rotary else "m"
        lines = [f"mass m = {e.mass:.2f} ± {e.uncertainty:.2f} {kg} "
                 f"(u/m = {e.relative_uncertainty:.3%}), fitted a = {e.acceleration:.5f} {x}/s²",
                 f"pair masses {e.pairs[0].mass:.2f} {kg}, {e.pairs[1].mass:.2f} {kg}; "
                 + (f"calibration I = {e.beta[0]:.6f} A/{x} x + {e.beta[1]:.6f} A"
                    if e.calibration is not None else "no calibration"),
                 f"table row {self.row.number} (inert >= {self.row.inert:g} {kg}), axis "
                 f"Q0 = {self.values[0]:g}: "
                 + ", ".join(f"{n} {self.values[MP_Q[n]]:g}" for n in MP_NAMES[:6]) + ", ..."]
        if self.output:
            lines.append(f"parameter macro written to {self.output}")
        return "\n".join(lines)


def unit(e: Estimate) -> str:
    """The estimate's unit: a mass, or a moment of inertia for a rotary axis."""
    return "kg·m²" if e.measurement.rotary else "kg"


Confirm = Callable[["TuneResult"], bool]


def tune_files(settings: str | Path, calibration: str | Path | None, measurement: str | Path,
               template: str | Path, output: str | Path | None,
               confirm: Confirm | None = None) -> TuneResult:
    """The offline run: files in, MPSet.H out (None: estimate and select only)."""
    s = read_settings(settings)
    cal = read_input(calibration) if calibration is not None else None
    meas = read_input(measurement)
    tpl = MPFile.read(template)
    return tune(s, cal, meas, tpl, output, confirm)


def read_input(path: str | Path) -> Any:
    """A recording: plain CSV with named columns and units (`.csv`) or the scope's `.dta`."""
    if Path(path).suffix.lower() == ".csv":
        return read_csv(path)
    return read_recording(path)


def tune(s: Settings, cal: Any, meas: Any, tpl: MPFile,
         output: str | Path | None, confirm: Confirm | None = None) -> TuneResult:
    """Estimate, select the row, patch the template; write `output` only if all succeeded
    and `confirm(result)` (the thesis's mass window) accepts."""
    est = estimate(meas, cal, s)
    row = s.table.select(est.mass)
    before = tpl.values()
    values = s.table.resolve(row, before)
    data = tpl.patched(values)
    if confirm is not None and not confirm(TuneResult(est, row, values, None, before)):
        raise MassEstimationError(f"m = {est.mass:.1f} kg, row {row.number}: not confirmed; "
                                  "nothing written")
    out = None
    if output is not None:
        out = Path(output)
        write_atomic(out, data)
    return TuneResult(est, row, values, out, before)


def write_example(directory: str | Path, mass: float = 22699.0, seed: int = 0,
                  noise: bool = True, geometry: str = "settings",
                  table: str = "thesis") -> dict[str, Path]:
    """Settings (thesis Fig. 3-1 + table), template, and seeded synthetic recordings of an
    axis of the given mass: a complete input set for `softplc tune`. `geometry` "macro"
    uses the NC macro's 100 mm triangle moves at 0.4 m/s² instead of the settings file's
    300 mm at 0.22 m/s²; `table` "machine" the simulated machine's parameter table
    (`retune.machine_table_text`) instead of the thesis's."""
    from softplc.machines.machining.retune import settings_with_table
    from softplc.machines.machining.synth import (
        Scenario,
        macro_scenario,
        macro_settings,
        recordings,
    )

    if geometry not in GEOMETRIES:
        raise MassEstimationError(f"geometry {geometry!r}: expected one of "
                                  f"{', '.join(GEOMETRIES)}")
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    macro = geometry == "macro"
    sc = macro_scenario(mass=mass, seed=seed) if macro else Scenario(mass=mass, seed=seed)
    cal, meas = recordings(sc if noise else sc.without_noise())
    paths = {"settings": d / SETTINGS_FILE, "template": d / TEMPLATE_FILE,
             "calibration": d / CAL_FILE, "measurement": d / MEAS_FILE}
    settings = settings_with_table(macro_settings() if macro else thesis_settings(), table)
    write_atomic(paths["settings"], format_settings(settings).encode())
    write_atomic(paths["template"], default_template(settings.table.axis))
    write_recording(cal, paths["calibration"])
    write_recording(meas, paths["measurement"])
    return paths
