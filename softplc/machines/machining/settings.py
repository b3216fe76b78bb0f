"""The settings and inputs file (mass-estimation.md §3.1, thesis Fig. 3-1 and annex 9.10).

Text, one ``Name = value (comment)`` per line: ``Settings.``, four ``CHANNELID# = id : NAME``
lines (position, velocity, acceleration, torque: order fixed), ``Inputs`` with the numbers
below, then the parameter table (``idx = N``, ``#\\param inert MP...``, rows).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from softplc.errors import MassFileError
from softplc.machines.machining.files import read_text
from softplc.machines.machining.params import ParameterTable, parse_table

CHANNEL_ROLES = ("ACTUAL POSITION", "ACTUAL VELOCITY", "ACTUAL ACCELERATION", "ACTUAL MOMENTUM")

# settings-file name -> (field, comment written by `format_settings`)
_INPUTS = {
    "Pos_conv": ("pos_conv", "[system units of position] to [SI units of position]"),
    "Vel_conv": ("vel_conv", "[system units of velocity] to [SI units of velocity]"),
    "Acc_conv": ("acc_conv", "[system units of acceleration] to [SI units of acceleration]"),
    "Start_Cal": ("start_cal", "[system units of position] Start position of calibration "
                               "measurement"),
    "End_Cal": ("end_cal", "[system units of position] End position of calibration "
                           "measurement"),
    "Start_m": ("start_m", "[system units of position] Start position of main measurement "
                           "of inertia"),
    "End_m": ("end_m", "[system units of position] End position of main measurement of "
                       "inertia"),
    "A_lim": ("a_lim", "[system units of acceleration] Limit acceleration set on machine"),
    "MinT": ("min_t", "Minimum time interval of constant acceleration"),
    "Margin": ("margin", "Estimation of relative part of acceleration signal where it is not "
                         "constant yet"),
    "Km_sys": ("km_sys", "Torque constant in control system"),
    "Correction": ("correction", "Correction of torque constant"),
    "Acc_uncert": ("acc_uncert", "Accepted uncertainty for reduced mass value"),
    "Ratio": ("ratio", "Ratio of change"),
}


@dataclass(frozen=True)
class Settings:
    """Inputs of the estimator, in the file's (system) units; defaults = thesis Fig. 3-1."""

    table: ParameterTable
    channel_ids: tuple[int, int, int, int] = (2, 6, 19, 29)
    pos_conv: float = 0.001
    vel_conv: float = 1.66667e-5
    acc_conv: float = 1.0
    start_cal: float = -480.0
    end_cal: float = -120.0
    start_m: float = -450.0
    end_m: float = -150.0
    a_lim: float = 0.22
    min_t: float = 0.2
    margin: float = 0.2
    km_sys: float = 1.687
    correction: float = 1.0
    acc_uncert: float = 0.05
    ratio: float = 523.5987756
    file: str = field(default="<settings>", compare=False)

    @property
    def a_lim_si(self) -> float:
        return self.a_lim * self.acc_conv

    def validate(self) -> Settings:
        """Raise MassFileError naming the first input out of its range."""
        def bad(name: str, expected: str) -> MassFileError:
            return MassFileError(f"{self.file}: {name} = {getattr(self, _INPUTS[name][0])!r}: "
                                 f"expected {expected}")

        for name, (attr, _) in _INPUTS.items():
            if not math.isfinite(getattr(self, attr)):
                raise bad(name, "a finite number")
        for name in ("Pos_conv", "Vel_conv", "Acc_conv", "MinT", "Km_sys", "Correction",
                     "Acc_uncert", "Ratio"):
            if getattr(self, _INPUTS[name][0]) <= 0:
                raise bad(name, "a number > 0")
        if self.a_lim == 0:
            raise bad("A_lim", "a nonzero acceleration")
        if not 0 <= self.margin < 0.5:
            raise bad("Margin", "a fraction per end in [0, 0.5)")
        if self.start_cal == self.end_cal:
            raise bad("End_Cal", f"a position different from Start_Cal ({self.start_cal:g})")
        lo, hi = sorted((self.start_cal, self.end_cal))
        if self.start_m == self.end_m:
            raise bad("End_m", f"a position different from Start_m ({self.start_m:g})")
        for name in ("Start_m", "End_m"):
            if not lo <= getattr(self, _INPUTS[name][0]) <= hi:
                raise bad(name, f"a position inside the calibration range {lo:g}..{hi:g}")
        if len(set(self.channel_ids)) != 4:
            raise MassFileError(f"{self.file}: CHANNELID#: four different IDs expected, got "
                                f"{list(self.channel_ids)}")
        return self


_LINE = re.compile(r"^\s*([A-Za-z_#][\w#]*)\s*=\s*([^(:]*?)\s*(?:[:(].*)?$")


def parse_settings(text: str, file: str = "<settings>") -> Settings:
    ids: list[int] = []
    values: dict[str, float] = {}
    table_lines: list[tuple[int, str]] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        s = raw.strip()
        if not s or s.rstrip(".").lower() in ("settings", "inputs"):
            continue
        if table_lines or s.lower().startswith("idx") or s.startswith("#"):
            table_lines.append((lineno, s))
            continue
        m = _LINE.match(s)
        if not m:
            raise MassFileError(f"{file}:{lineno}: {s!r}: expected 'Name = value (comment)'")
        key, val = m[1], m[2]
        if key.upper() == "CHANNELID#":
            try:
                ids.append(int(val))
            except ValueError:
                raise MassFileError(f"{file}:{lineno}: CHANNELID# {val!r}: expected an "
                                    "integer channel ID") from None
            continue
        if key not in _INPUTS:
            raise MassFileError(f"{file}:{lineno}: unknown input {key!r}; expected one of "
                                f"{', '.join(_INPUTS)}")
        if key in values:
            raise MassFileError(f"{file}:{lineno}: {key} given twice")
        try:
            values[key] = float(val)
        except ValueError:
            raise MassFileError(f"{file}:{lineno}: {key} = {val!r}: expected a number") from None
    if len(ids) != 4:
        raise MassFileError(f"{file}: {len(ids)} CHANNELID# lines, expected 4 ("
                            f"{', '.join(CHANNEL_ROLES)}, in this order)")
    missing = [k for k in _INPUTS if k not in values]
    if missing:
        raise MassFileError(f"{file}: missing input{'s' if len(missing) > 1 else ''} "
                            f"{', '.join(missing)}")
    table = parse_table(table_lines, file)
    kw = {_INPUTS[k][0]: v for k, v in values.items()}
    return Settings(table=table, channel_ids=tuple(ids), file=file, **kw).validate()


def read_settings(path: str | Path) -> Settings:
    return parse_settings(read_text(path, "settings file"), str(path))


def format_settings(s: Settings) -> str:
    """The settings file text (`parse_settings(format_settings(s)) == s`)."""
    out = ["Settings.", ""]
    out += [f"CHANNELID# = {i} : {role}" for i, role in zip(s.channel_ids, CHANNEL_ROLES,
                                                              strict=True)]
    out += ["", "Inputs", ""]
    for name, (attr, comment) in _INPUTS.items():
        out.append(f"{name} = {getattr(s, attr)!r} ({comment})")
    t = s.table
    out += ["", f"idx = {t.axis}", "#\\param inert " + " ".join(t.columns)]
    for r in t.rows:
        cells = [str(r.number), repr(r.inert)]
        cells += ["x" if r.values[c] is None else repr(r.values[c]) for c in t.columns]
        out.append(", ".join(cells) + ",")
    return "\n".join(out) + "\n"


THESIS_TABLE_TEXT = """\
idx = 0
#\\param inert MP2500 MP2510 MP2562 MP2552 MP2542 MP2572
1, 0, 3550, 44.5, 0, 0, 0, 0,
2, 20000, 3650, 45.5, 1, 700, x, 0,
"""


def thesis_settings() -> Settings:
    """The thesis's settings file (Fig. 3-1) with its parameter table (Fig. 3-40)."""
    lines = list(enumerate(THESIS_TABLE_TEXT.splitlines(), 1))
    return Settings(table=parse_table(lines, "<thesis table>"), file="<thesis settings>")

