"""The cutting table's host side: path library, seed mode, pieces, preview, PLC words.

    from softplc.machines.cutting import load_piece, piece_words, preview
    piece = load_piece("ladder_programs/pieces/achaflanado.toml")
    segs = piece.segments()               # numbered straight moves, cut or move
    for words in piece_words(segs):       # each with the look-ahead of the next one
        frame = words.frame()             # %MW100..%MW108 as the host writes them
    preview(piece, "e3.png", seed=True)

Geometry in `geometry.py` (line, arc, fillet, Newton curve, chord tolerance), the axis split
in `motion.py`, the thesis's defective algorithms in `seed.py`, pieces from TOML / G-code in
`piece.py` (from DXF in `dxf.py`; `load.py` picks by suffix), the register words in
`regmap.py`. See docs/machines/cutting-table.md.
"""

from softplc.machines.cutting.geometry import (
    Arc,
    CoincidentPointsError,
    CuttingError,
    Fillet,
    FilletError,
    GeometryError,
    Line,
    NewtonCurve,
    NewtonError,
    ZeroRadiusError,
    fillet,
)
from softplc.machines.cutting.load import load_piece
from softplc.machines.cutting.motion import LineSplit, Trapezoid, matlab_steps, split_line
from softplc.machines.cutting.piece import (
    Piece,
    PieceError,
    Segment,
    piece_from_dict,
    piece_from_gcode,
)
from softplc.machines.cutting.preview import preview
from softplc.machines.cutting.regmap import SegmentWords, piece_words, segment_words

__all__ = [
    "Arc",
    "CoincidentPointsError",
    "CuttingError",
    "Fillet",
    "FilletError",
    "GeometryError",
    "Line",
    "LineSplit",
    "NewtonCurve",
    "NewtonError",
    "Piece",
    "PieceError",
    "Segment",
    "SegmentWords",
    "Trapezoid",
    "ZeroRadiusError",
    "fillet",
    "load_piece",
    "matlab_steps",
    "piece_from_dict",
    "piece_from_gcode",
    "piece_words",
    "preview",
    "segment_words",
    "split_line",
]
