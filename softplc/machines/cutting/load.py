"""A piece from a file, by its suffix: TOML (piece.py's schema), DXF (dxf.py) or G-code
(`piece.piece_from_gcode`).

Apart from piece.py so that the readers sit above the piece model: dxf.py builds a
`Piece`, and this module picks the reader.
"""

from __future__ import annotations

from pathlib import Path

from softplc.config import read_toml
from softplc.errors import ConfigError
from softplc.machines.cutting.dxf import piece_from_dxf
from softplc.machines.cutting.geometry import Point
from softplc.machines.cutting.piece import Piece, PieceError, piece_from_dict, piece_from_gcode

#: Options a caller (the command line) may impose on a piece, and their TOML keys.
OPTION_KEYS = {"speed": "speed", "move_speed": "move_speed", "accel": "accel",
               "tolerance": "chord_tolerance", "work_area": "work_area"}


def load_piece(path: str | Path, **options: float | Point | None) -> Piece:
    """A piece from a `.toml` file, a `.dxf` drawing (`dxf.py`), or G-code (any other
    suffix).

    `options` (speed, move_speed, accel, tolerance, work_area; None = not given) are the
    G-code reading values, and override the TOML file's keys."""
    p = Path(path)
    given = {k: v for k, v in options.items() if v is not None}
    unknown = set(given) - set(OPTION_KEYS)
    if unknown:
        raise TypeError(f"unknown piece options {sorted(unknown)}")
    if p.suffix.lower() == ".dxf":
        return piece_from_dxf(p, **given)
    if p.suffix.lower() != ".toml":
        return piece_from_gcode(p, **given)
    try:
        data = read_toml(p)
    except ConfigError as e:
        raise PieceError(str(e)) from None
    data.update({OPTION_KEYS[k]: v for k, v in given.items()})
    return piece_from_dict(data, str(p))
