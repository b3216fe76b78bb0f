"""The PMAC servo parameters (I-variables) and the PID + feed-forward law's coefficients.

Per servo cycle n, with AP the encoder count, CP the commanded position, FE = CP - AP,
CV, CA the commanded velocity and acceleration (counts per cycle, per cycle^2), AV the
actual velocity and IE the integrated error [manual: PMAC User Manual, "Actual PID
algorithm"; the thesis's appendix D reproduces the same code]:

    u = 2^-19 Ixx30 { Ixx08 [FE + (Ixx32 CV + Ixx35 CA) / 128 + Ixx33 IE / 2^23]
                      - Ixx31 Ixx09 AV / 128 }
    u += Ixx68 sgn(CV) + Ixx29, clamped to +-Ixx69                       (16-bit DAC units)

IE accumulates FE when (Ixx34 = 0 or CV = 0) and the previous output was not clamped
(anti-windup); `Ixx63` > 0 also bounds |IE| (in 1/16 count [choice]: the thesis leaves it
unset). `Coefficients.of(gains)` folds the scale factors into one multiplier per term, so
the servo loop does five multiplications.

Every parameter has two names, the PMAC I-variable with `xx` for the motor number and a
plain word; a TOML table may use either (`Ixx30 = 7990` or `kp = 7990`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import ConfigDict, Field, create_model, model_validator

# One table: (I-variable, plain name, default, meaning). The docs' table is generated
# from the same rows (`markdown_table`).
IVARS: tuple[tuple[str, str, float, str], ...] = (
    ("Ixx08", "pos_scale", 96, "position-loop scale factor"),
    ("Ixx09", "vel_scale", 96, "velocity-loop scale factor"),
    ("Ixx11", "fatal_fe", 65536, "fatal following error, 1/16 count (0 = off)"),
    ("Ixx12", "warn_fe", 6554, "warning following error, 1/16 count (0 = off)"),
    ("Ixx19", "max_accel", 2.048, "max jog/home acceleration, counts/ms^2 (0 = no limit)"),
    ("Ixx20", "accel_time", 125, "jog/home acceleration time, ms"),
    ("Ixx21", "scurve_time", 40, "jog/home S-curve time, ms"),
    ("Ixx22", "jog_speed", 204.8, "jog speed (and default move speed), counts/ms"),
    ("Ixx23", "home_speed", 3.413333, "homing speed, counts/ms; its sign is the direction"),
    ("Ixx26", "home_offset", 0, "home offset, 1/16 count"),
    ("Ixx28", "in_position", 160, "in-position band, 1/16 count"),
    ("Ixx29", "offset", 0, "output offset, DAC bits"),
    ("Ixx30", "kp", 0, "proportional gain"),
    ("Ixx31", "kd", 0, "derivative gain (on the actual velocity)"),
    ("Ixx32", "kvff", 0, "velocity feed-forward gain"),
    ("Ixx33", "ki", 0, "integral gain"),
    ("Ixx34", "int_mode", 0, "integration mode: 0 always, 1 only while CV = 0"),
    ("Ixx35", "kaff", 0, "acceleration feed-forward gain"),
    ("Ixx60", "servo_ext", 0, "servo cycle extension: the loop runs every Ixx60+1 clocks"),
    ("Ixx63", "int_limit", 0, "integration limit, 1/16 count (0 = none)"),
    ("Ixx68", "friction_ff", 0, "friction feed-forward, DAC bits, sign of CV"),
    ("Ixx69", "output_limit", 32767, "output limit, DAC bits"),
)


# The range each I-variable accepts: (min, max, min exclusive, source). PMAC I-variables
# are 24-bit registers (-8,388,608 .. 8,388,607) unless noted; the sources are the Delta
# Tau manuals: SRM = "Turbo PMAC/PMAC2 Software Reference", section "Turbo PMAC Global
# I-Variables" (page), PMAC SRM = the non-Turbo "PMAC/PMAC2 Software Reference",
# "PMAC I-Variable Specification" (page), QRG = "PMAC Quick Reference Guide", Appendix B
# "PMAC I-Variables Summary". A PMAC rolls an out-of-range value over (Turbo PMAC User
# Manual, "Limited Range"); the axis refuses it instead, so a typing error never becomes
# a different gain [choice].
# docs/servo-gains.md shows this table (`range_table`).
I24_MAX = 2 ** 23 - 1  # 8,388,607: the largest value of a 24-bit register
I24_MIN = -(2 ** 23)
DAC_MAX = 2 ** 15 - 1  # 32,767: a 16-bit DAC's largest output
DAC_MIN = -(2 ** 15)
QRG_SAFETY = "QRG, Motor Safety I-Variables"
QRG_MOVE = "QRG, Motor Movement I-Variables"
QRG_SERVO = "QRG, Servo Control I-Variables"
QRG_MOD = "QRG, Motor Servo Loop Modifiers"
NO_MAX = ("SRM p.100 (Ixx19), p.101 (Ixx22): 'positive floating point', no upper bound; "
          "the 24-bit range of its neighbours Ixx20/21 [choice]")
RANGES: dict[str, tuple[float, float, bool, str]] = {
    "Ixx08": (0, I24_MAX, True, "PMAC SRM p.63 (Ix09 0 .. 8,388,607; Ix08 the same "
              "[manual, from memory]); 0 would zero the law [choice]"),
    "Ixx09": (0, I24_MAX, True, "PMAC SRM p.63, Ix09: 0 .. 8,388,607; 0 refused as Ixx08"),
    "Ixx11": (0, I24_MAX, False, QRG_SAFETY + "; 0 = off (SRM p.96 [manual, from memory])"),
    "Ixx12": (0, I24_MAX, False, QRG_SAFETY),
    "Ixx19": (0, I24_MAX, False, NO_MAX),
    "Ixx20": (0, I24_MAX, False, QRG_MOVE + "; SRM p.101"),
    "Ixx21": (0, I24_MAX, False, QRG_MOVE + "; SRM p.101"),
    "Ixx22": (0, I24_MAX, False, NO_MAX),
    "Ixx23": (-I24_MAX, I24_MAX, False, "SRM p.101: 'floating point', no bound; the "
              "24-bit range either way [choice]"),
    "Ixx26": (I24_MIN, I24_MAX, False, QRG_MOVE),
    "Ixx28": (0, I24_MAX, False, QRG_MOVE),
    "Ixx29": (DAC_MIN, DAC_MAX, False, QRG_MOVE),
    "Ixx30": (0, I24_MAX, False, "SRM p.111: -8,388,608 .. 8,388,607; a negative gain "
              "inverts the output polarity (wiring), not modelled: >= 0 [choice]"),
    "Ixx31": (0, I24_MAX, False, QRG_SERVO + ": signed; >= 0 as Ixx30 [choice]"),
    "Ixx32": (0, I24_MAX, False, QRG_SERVO),
    "Ixx33": (0, I24_MAX, False, QRG_SERVO),
    "Ixx34": (0, 1, False, QRG_SERVO),
    "Ixx35": (0, I24_MAX, False, QRG_SERVO),
    "Ixx60": (0, 255, False, QRG_MOD),
    "Ixx63": (0, I24_MAX, False, QRG_MOD + ": signed; a negative limit is not modelled: "
              ">= 0 [choice]"),
    "Ixx68": (0, DAC_MAX, False, "SRM p.127 (Turbo: 0 .. 32,767)"),
    "Ixx69": (0, DAC_MAX, True, "SRM p.127: 0 .. 32,767; 0 would hold the output at 0 "
              "[choice]"),
}
_INTEGER = {"Ixx34", "Ixx60"}


def _field(ivar: str, default: float, meaning: str) -> tuple[type, Any]:
    lo, hi, open_lo, _ = RANGES[ivar]
    low = {"gt": lo} if open_lo else {"ge": lo}
    if ivar in _INTEGER:
        return int, Field(int(default), alias=ivar, le=hi, description=meaning, **low)
    return float, Field(float(default), alias=ivar, description=meaning, allow_inf_nan=False,
                        le=hi, **low)


def _one_name_each(data: Any) -> Any:
    """A parameter given by both its names is an error, not a silent choice."""
    if isinstance(data, dict):
        for ivar, name, _, _ in IVARS:
            if ivar in data and name in data:
                raise ValueError(f"{ivar} and {name} are the same parameter: give one")
    return data


# The I-variables of one motor (TOML table `[devices.NAME.ivars]`); fields by plain name.
Gains = create_model(
    "Gains", __config__=ConfigDict(extra="forbid", populate_by_name=True),
    __validators__={"one_name_each": model_validator(mode="before")(_one_name_each)},
    **{name: _field(ivar, default, meaning) for ivar, name, default, meaning in IVARS})


def range_table() -> str:
    """The I-variables' accepted ranges with their sources, as markdown (docs)."""
    rows = ["| I-variable | plain name | accepted | source |", "|---|---|---|---|"]
    for ivar, name, _, _ in IVARS:
        lo, hi, open_lo, src = RANGES[ivar]
        rows.append(f"| {ivar} | `{name}` | {lo:,} {'<' if open_lo else '<='} x <= {hi:,} "
                    f"| {src} |")
    return "\n".join(rows)


def markdown_table() -> str:
    """The I-variable table as markdown (docs/machines/servo-table.md)."""
    rows = ["| I-variable | plain name | default | meaning |", "|---|---|---|---|"]
    rows += [f"| {i} | `{n}` | {d:g} | {m} |" for i, n, d, m in IVARS]
    return "\n".join(rows)


@dataclass(frozen=True)
class Coefficients:
    """The law with its scale factors folded in: u = fe*FE + cv*CV + ca*CA + ie*IE - av*AV."""

    fe: float
    cv: float
    ca: float
    ie: float
    av: float

    @classmethod
    def of(cls, g: Any) -> Coefficients:
        c = g.kp / 2 ** 19
        return cls(fe=c * g.pos_scale, cv=c * g.pos_scale * g.kvff / 128,
                   ca=c * g.pos_scale * g.kaff / 128, ie=c * g.pos_scale * g.ki / 2 ** 23,
                   av=c * g.kd * g.vel_scale / 128)


def law_output(c: Coefficients, g: Any, fe: float, cv: float, ca: float, ie: float,
               av: float) -> float:
    """The law's output before its limit (the generated loop's expression, for the
    bumpless change of gains: both laws are compared on one tick's terms)."""
    u = c.fe * fe + c.cv * cv + c.ca * ca + c.ie * ie - c.av * av + g.offset
    return u + (g.friction_ff if cv > 0 else -g.friction_ff if cv < 0 else 0.0)
