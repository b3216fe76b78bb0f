"""Machine parameters of the speed controller and filters, the parameter table (rows by mass)
and the default parameter-macro template (mass-estimation.md §3.2, §3.4).

The macro assigns Q0 = axis index, Q1 = MP2500 (speed Kp), Q2 = MP2510 (speed integral
factor) and, for filter n = 1..5, Qn1..Qn4 = type MP256(n+1), frequency MP255(n+1),
damping MP254(n+1), bandwidth MP257(n+1); then FN 17 writes the 22 MPs of axis Q0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from softplc.errors import MassFileError, TableRowError
from softplc.machines.machining import mpfile

AXIS_Q = 0  # Q0: index of the machine axis the MPs are written to
FILTERS = 5


def _filter_mps(n: int) -> list[tuple[str, int, float, str]]:
    """(MP name, Q number, template value, comment) of filter n (1-based)."""
    return [
        (f"MP256{n + 1}", 10 * n + 1, 0.0, f"type of filter {n}"),
        (f"MP255{n + 1}", 10 * n + 2, 250.0, f"frequency of filter {n} Hz"),
        (f"MP254{n + 1}", 10 * n + 3, 20.0, f"damping of filter {n} dB"),
        (f"MP257{n + 1}", 10 * n + 4, 50.0, f"bandwidth of filter {n} Hz"),
    ]


# The 22 MPs in macro order: (name, Q number, template value of MPSetTemp.H, comment)
MP_DEFS: list[tuple[str, int, float, str]] = [
    ("MP2500", 1, 3350.0, "value of MP2500 proportional factor of speed CTRL A*s"),
    ("MP2510", 2, 43.5, "value of MP2510 integral factor of speed CTRL A"),
    *[d for n in range(1, FILTERS + 1) for d in _filter_mps(n)],
]
MP_NAMES = [d[0] for d in MP_DEFS]
# Input ranges stated in the HEIDENHAIN Technical Manual TNC 426/430 (p. 6-135) [manual];
# the filter MPs' ranges are not known here (only >= 0 is checked).
MP_MAX = {"MP2500": 1_000_000.0, "MP2510": 100_000_000.0}
MP_Q = {d[0]: d[1] for d in MP_DEFS}
TEMPLATE_VALUES = {d[0]: d[2] for d in MP_DEFS}

# The thesis's template header comments (Fig. 3-42)
_TEMPLATE_HEAD = ["(Setting MP parameters)", "(MACHINE: VIRTUAL STATION)",
                  "(SYSTEM: Heidenhain)", "(JAZYK: Dialog)", "(" + "=" * 35 + ")",
                  " parameters"]


def _q_comment(q: int, text: str) -> str:
    # Q0's comment has no colon in the thesis's dump; Q1, Q2 are " Qn:    text"
    return f" Q{q} {text}" if q == AXIS_Q else f" Q{q}:    {text}"


def default_template(axis: int = 0) -> bytes:
    """MPSetTemp.H in the known layout with the thesis's template values. Its first 400 bytes
    equal the thesis's dump (Fig. 3-42); the FN 17 lines (encoding unknown) are absent."""
    items: list[tuple[str, object]] = [("comment", c) for c in _TEMPLATE_HEAD]
    items.append(("q", (AXIS_Q, float(axis), _q_comment(AXIS_Q, "index of machine tool axis"))))
    items += [("q", (q, v, _q_comment(q, c))) for _, q, v, c in MP_DEFS]
    return mpfile.build(items)


@dataclass(frozen=True)
class Row:
    number: int
    inert: float  # minimum mass of the row, kg
    values: dict[str, float | None]  # MP name -> value, None = keep the template's ('x')
    line: int = field(default=0, compare=False)


@dataclass(frozen=True)
class ParameterTable:
    """`idx` (axis index) and rows ordered by their minimum mass `inert`."""

    axis: int
    columns: list[str]
    rows: list[Row]

    def select(self, mass: float) -> Row:
        """The last row with inert <= mass (`inert` is the row's minimum mass)."""
        if not (isinstance(mass, float | int) and math.isfinite(mass)) or mass <= 0:
            raise TableRowError(f"mass {mass!r} kg: expected a positive finite number")
        fitting = [r for r in self.rows if r.inert <= mass]
        if not fitting:
            raise TableRowError(f"mass {mass:.1f} kg is below the first row of the parameter "
                                f"table (inert = {self.rows[0].inert:g} kg)")
        return fitting[-1]

    def resolve(self, row: Row, template: dict[int, float]) -> dict[int, float]:
        """Q number -> value to write: the row's values, 'x' and absent columns from the
        template (Q -> value as read from MPSetTemp.H), Q0 = the axis index."""
        out = {AXIS_Q: float(self.axis)}
        for name in MP_NAMES:
            q = MP_Q[name]
            v = row.values.get(name)
            if v is None:
                if q not in template:
                    raise MassFileError(f"template has no Q{q} ({name}) for row {row.number}")
                v = template[q]
            out[q] = v
        return out


def parse_table(lines: list[tuple[int, str]], file: str) -> ParameterTable:
    """The table part of the settings file: `idx = N`, a `#\\param inert MP...` header and
    rows `number, inert, values...,` (trailing comma allowed; `x` keeps the template value)."""
    axis: int | None = None
    columns: list[str] | None = None
    rows: list[Row] = []
    for lineno, text in lines:
        where = f"{file}:{lineno}"
        s = text.strip()
        if s.lower().startswith("idx"):
            _, _, val = s.partition("=")
            try:
                axis = int(val.split("(")[0].strip())
            except ValueError:
                raise MassFileError(f"{where}: idx {val.strip()!r}: expected an axis "
                                    "index (integer >= 0)") from None
            if axis < 0:
                raise MassFileError(f"{where}: idx {axis}: expected an integer >= 0")
        elif s.startswith("#"):
            words = s.lstrip("#").split()
            if len(words) < 2 or words[1].lower() != "inert":
                raise MassFileError(f"{where}: table header {s!r}: expected "
                                    "'#\\param inert MP2500 ...'")
            columns = words[2:]
            unknown = [c for c in columns if c not in MP_Q]
            if unknown:
                raise MassFileError(f"{where}: unknown parameter {unknown[0]!r}; expected one "
                                    f"of {', '.join(MP_NAMES)}")
            if len(set(columns)) != len(columns):
                raise MassFileError(f"{where}: a parameter appears twice in the header")
        else:
            if columns is None:
                raise MassFileError(f"{where}: table row before the '#\\param inert' header")
            cells = [c.strip() for c in s.split(",")]
            if cells and cells[-1] == "":
                cells.pop()
            if len(cells) != 2 + len(columns):
                raise MassFileError(f"{where}: row has {len(cells)} cells, expected "
                                    f"{2 + len(columns)} (number, inert, {', '.join(columns)})")
            try:
                number = int(cells[0])
            except ValueError:
                raise MassFileError(f"{where}: row number {cells[0]!r}: expected an "
                                    "integer") from None
            inert = _cell(cells[1], f"{where}: inert", allow_x=False)
            values = {c: _cell(v, f"{where}: {c}", allow_x=True, top=MP_MAX.get(c))
                      for c, v in zip(columns, cells[2:], strict=True)}
            if rows and inert <= rows[-1].inert:  # type: ignore[operator]
                raise MassFileError(f"{where}: inert {inert:g} kg: rows must be in increasing "
                                    f"order of mass (previous row {rows[-1].inert:g} kg)")
            rows.append(Row(number, inert, values, lineno))  # type: ignore[arg-type]
    if axis is None:
        raise MassFileError(f"{file}: no 'idx = N' (axis index) before the parameter table")
    if columns is None or not rows:
        raise MassFileError(f"{file}: no parameter table ('#\\param inert ...' and rows)")
    return ParameterTable(axis, columns, rows)


def _cell(text: str, where: str, *, allow_x: bool, top: float | None = None) -> float | None:
    if allow_x and text.lower() == "x":
        return None
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v) or v < 0 or (top is not None and v > top):
        raise MassFileError(f"{where} {text!r}: expected a real number >= 0"
                            + (f" and <= {top:g}" if top is not None else "")
                            + (" or 'x' (keep the template's value)" if allow_x else ""))
    return v
