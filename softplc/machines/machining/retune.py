"""What the drive does with the machine parameters the PLC applies (the thesis's macro 2,
FN 17 SYSWRITE of MP2500/MP2510 at standstill), and the parameter table of the simulated
machining centre.

The thesis's speed loop keeps its total gain K_R = Kp Km / (J Tn) constant: Kp and the
integral factor grow with the moving mass (eq. 2-1, mass-estimation.md §1). Our axis is a
PMAC loop whose Ixx30 multiplies the whole law (position, damping and feed-forward terms),
so the drive maps the active MPs onto the I-variables the axis was commissioned with
(`reference`: the MPs those I-variables correspond to, the template's by default) [choice]:

    s = MP2500 / MP2500_ref              Ixx30' = s Ixx30     (stiffness, damping, Kaff ~ m)
    Ixx32' = Ixx31 + (Ixx32 - Ixx31) / s  (the part of Kvff beyond Kd is the viscous
                                           feed-forward: a force, it does not grow with m)
    Ixx33' = Ixx33 (MP2510 / MP2510_ref) / s   (the integral term follows MP2510)

The filter MPs (MP254x-MP257x) have no counterpart in the axis model and are ignored.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from softplc.errors import ConfigError
from softplc.machines.machining.names import TABLES
from softplc.machines.machining.params import MP_NAMES, TEMPLATE_VALUES, parse_table
from softplc.machines.machining.settings import Settings, thesis_settings

DRIVE_MPS = ("MP2500", "MP2510")  # the MPs the drive model uses
REFERENCE = {n: TEMPLATE_VALUES[n] for n in DRIVE_MPS}  # MPSetTemp.H: the commissioning


def gain_changes(gains: Any, active: Mapping[str, float],
                 reference: Mapping[str, float] = REFERENCE) -> dict[str, float]:
    """The I-variables (plain names) that `active` MPs give, from the commissioned `gains`
    (a `law.Gains`) tuned for the `reference` MPs. Refuses what no drive would accept."""
    for name in DRIVE_MPS:
        v, ref = active.get(name, math.nan), reference.get(name, math.nan)
        if not (math.isfinite(ref) and ref > 0):
            raise ConfigError(f"reference {name} = {ref!r}: expected a number > 0")
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(f"{name} = {v!r}: expected a number > 0")
    s = active["MP2500"] / reference["MP2500"]
    si = active["MP2510"] / reference["MP2510"]
    return {"kp": gains.kp * s, "kvff": gains.kd + (gains.kvff - gains.kd) / s,
            "ki": gains.ki * si / s}


def retuned(gains: Any, active: Mapping[str, float],
            reference: Mapping[str, float] = REFERENCE) -> Any:
    """A new validated `law.Gains` (the commissioned one is left as it is)."""
    from pydantic import ValidationError

    data = gains.model_dump()
    data.update(gain_changes(gains, active, reference))
    try:
        return type(gains).model_validate(data)
    except ValidationError as e:
        raise ConfigError(f"retuned gains refused: {e.errors()[0]['msg']}") from None


def mp_dict(values: list[float] | tuple[float, ...]) -> dict[str, float]:
    """The 22 MPs in macro order (MP_NAMES), as the PLC holds them, by name."""
    if len(values) != len(MP_NAMES):
        raise ConfigError(f"{len(values)} machine parameters, expected {len(MP_NAMES)}")
    return dict(zip(MP_NAMES, values, strict=True))


# The simulated machining centre's table (mass_tuning.toml: the bare table m0 = 15 t was
# commissioned with the template's MP2500 3350, MP2510 43.5): one row per 3 t, each tuned
# for the middle of its range, MP2500 and MP2510 in proportion to the mass (K_R constant).
MACHINE_M0 = 15000.0  # kg
MACHINE_ROWS = (0.0, 16500.0, 19500.0, 22500.0, 25500.0)  # inert: each row's minimum mass
_STEP = 3000.0


def machine_table_text() -> str:
    lines = ["idx = 0", "#\\param inert MP2500 MP2510"]
    for n, inert in enumerate(MACHINE_ROWS, 1):
        design = MACHINE_M0 + _STEP * (n - 1)  # the row's middle (row 1: the bare table)
        s = design / MACHINE_M0
        lines.append(f"{n}, {inert:g}, {REFERENCE['MP2500'] * s:g}, "
                     f"{REFERENCE['MP2510'] * s:g},")
    return "\n".join(lines) + "\n"


def settings_with_table(base: Settings | None, table: str) -> Settings:
    """`base` (default: the thesis's settings) with the thesis's table (Fig. 3-40) or the
    simulated machine's."""
    from dataclasses import replace

    s = base or thesis_settings()
    if table == "thesis":
        return s
    if table != "machine":
        raise ConfigError(f"table {table!r}: expected one of {', '.join(TABLES)}")
    lines = list(enumerate(machine_table_text().splitlines(), 1))
    return replace(s, table=parse_table(lines, "<machine table>"))
