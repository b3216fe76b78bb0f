"""Recordings as plain CSV with named columns and units (besides the scope's `.dta`).

The first line that is not blank or a `#` comment names the columns, each `name [unit]`
(or `name (unit)`); comma, semicolon or tab separated; one sample per line after it.
Columns are found by name (case-insensitive; other columns are ignored):

| role | names | units |
|---|---|---|
| time | t, time | s, ms, us |
| position | x, s, pos, position, angle | m, mm, um (linear); deg, rad (rotary) |
| velocity | v, vel, velocity, speed | m/s, mm/s, m/min, mm/min; deg/s, rad/s, 1/min, rpm |
| acceleration | a, acc, acceleration | m/s^2, mm/s^2; deg/s^2, rad/s^2 |
| torque | torque, m, momentum | Nm (current = -torque / Km_sys, eq. 3-2) |
| current | i, current | A (the drive's current, used as is) |

Time, position, velocity, acceleration and one of torque/current are required. Values are
converted to SI by their own units (a rotary axis: rad, rad/s, rad/s²); the settings'
Pos_conv / Acc_conv still convert the settings' own numbers (Start_Cal, A_lim...), so a
rotary axis's settings in degrees say Pos_conv = Acc_conv = 0.0174532925 (deg -> rad), and
Ratio is then motor rad per axis rad: the estimate is a moment of inertia, kg·m² [choice].
A current channel is where the spec allows it (§1: the thesis has none and computes it from
the torque): the estimator only uses current differences and a calibration line of the same
current, so its sign convention does not change the estimate.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softplc.errors import MassFileError, SingularFitError
from softplc.machines.machining.files import read_text

_RPM = 2 * math.pi / 60
_DEG = math.pi / 180
ROLES: dict[str, tuple[tuple[str, ...], dict[str, tuple[float, bool | None]]]] = {
    # role: (names, unit -> (factor to SI, rotary? None = either))
    "time": (("t", "time"), {"s": (1.0, None), "ms": (1e-3, None), "us": (1e-6, None),
                             "µs": (1e-6, None)}),
    "position": (("x", "s", "pos", "position", "angle"),
                 {"m": (1.0, False), "mm": (1e-3, False), "um": (1e-6, False),
                  "µm": (1e-6, False), "deg": (_DEG, True), "rad": (1.0, True)}),
    "velocity": (("v", "vel", "velocity", "speed"),
                 {"m/s": (1.0, False), "mm/s": (1e-3, False), "m/min": (1 / 60, False),
                  "mm/min": (1e-3 / 60, False), "deg/s": (_DEG, True), "rad/s": (1.0, True),
                  "1/min": (_RPM, True), "rpm": (_RPM, True)}),
    "acceleration": (("a", "acc", "acceleration"),
                     {"m/s^2": (1.0, False), "m/s2": (1.0, False), "m/(s*s)": (1.0, False),
                      "mm/s^2": (1e-3, False), "deg/s^2": (_DEG, True),
                      "rad/s^2": (1.0, True)}),
    "torque": (("torque", "m", "momentum"), {"nm": (1.0, None)}),
    "current": (("i", "current"), {"a": (1.0, None)}),
}
_HEADER = re.compile(r"^\s*([^\[(]+?)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


@dataclass(frozen=True)
class CsvRecording:
    """A CSV recording in SI units; `current` or `torque` as recorded (one may be None)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    torque: np.ndarray | None
    current: np.ndarray | None
    rotary: bool
    name: str = "<csv>"

    def to_trace(self, s) -> object:
        """The estimator's `Trace` (current = -torque / Km_sys without a current column)."""
        from softplc.machines.machining.estimator import Trace

        cur = self.current if self.current is not None else -self.torque / s.km_sys
        for role, col in (("position", self.x), ("velocity", self.v),
                          ("acceleration", self.a), ("current", cur)):
            if np.ptp(col) == 0:
                raise SingularFitError(f"{self.name}: the {role} column is flat: nothing to fit")
        return Trace(self.t, self.x, self.v, self.a, cur, self.name, self.rotary)


def _delimiter(line: str) -> str:
    return max((";", "\t", ","), key=line.count) if any(c in line for c in ";\t,") else ","


def parse_csv(text: str, name: str = "<csv>") -> CsvRecording:
    lines = [(n, s) for n, s in enumerate(text.splitlines(), 1)
             if s.strip() and not s.lstrip().startswith("#")]
    if not lines:
        raise MassFileError(f"{name}: no header line (columns 'name [unit]')")
    head_no, head = lines[0]
    sep = _delimiter(head)
    found: dict[str, tuple[int, float, bool | None]] = {}
    for col, cell in enumerate(head.split(sep)):
        m = _HEADER.match(cell)
        label, unit = (m[1].strip().lower(), (m[2] or "").strip()) if m else ("", "")
        for role, (names, units) in ROLES.items():
            if label in names:
                if role in found:
                    raise MassFileError(f"{name}:{head_no}: two {role} columns")
                key = unit if unit in units else unit.lower()
                if key not in units:
                    raise MassFileError(
                        f"{name}:{head_no}: column {cell.strip()!r}: unit {unit!r} for "
                        f"{role}; expected one of {', '.join(units)} (as 'name [unit]')")
                found[role] = (col, *units[key])
    missing = [r for r in ("time", "position", "velocity", "acceleration") if r not in found]
    if missing or not ("torque" in found or "current" in found):
        need = ", ".join(missing + ([] if "torque" in found or "current" in found
                                    else ["torque or current"]))
        raise MassFileError(f"{name}:{head_no}: no {need} column (header {head.strip()!r})")
    kinds = {found[r][2] for r in ("position", "velocity", "acceleration")}
    if len(kinds) != 1:
        raise MassFileError(f"{name}:{head_no}: position, velocity and acceleration mix "
                            "linear and rotary units")
    width = len(head.split(sep))
    rows = []
    for n, s in lines[1:]:
        cells = s.split(sep)
        try:
            if len(cells) != width:
                raise ValueError
            rows.append([float(c) for c in cells])
        except ValueError:
            raise MassFileError(f"{name}:{n}: {s.strip()!r}: expected {width} numbers") \
                from None
    data = np.array(rows, dtype=float).reshape(-1, width)
    if len(data) < 2 or not np.all(np.isfinite(data)):
        raise MassFileError(f"{name}: {len(data)} samples, or a value that is not finite")

    def col(role: str) -> np.ndarray | None:
        return data[:, found[role][0]] * found[role][1] if role in found else None

    t = col("time")
    assert t is not None
    if not np.all(np.diff(t) > 0):
        raise MassFileError(f"{name}: the time column must increase strictly")
    return CsvRecording(t, col("position"), col("velocity"), col("acceleration"),  # type: ignore[arg-type]
                        col("torque"), col("current"), kinds == {True}, name)


def read_csv(path: str | Path) -> CsvRecording:
    return parse_csv(read_text(path, "CSV recording"), str(path))


def format_csv(t: np.ndarray, x: np.ndarray, v: np.ndarray, a: np.ndarray, y: np.ndarray,
               units: tuple[str, str, str, str, str]) -> str:
    """A CSV recording of the given columns (already in `units`: time, position, velocity,
    acceleration, and torque Nm or current A)."""
    names = ("time", "position", "velocity", "acceleration",
             "current" if units[4].lower() == "a" else "torque")
    head = ",".join(f"{n} [{u}]" for n, u in zip(names, units, strict=True))
    body = "\n".join(",".join(f"{c:.9g}" for c in row)
                     for row in np.column_stack([t, x, v, a, y]))
    return head + "\n" + body + "\n"
