"""The cutting table's host side: path library, seed mode, pieces, preview, PLC words.

    from softplc.machines.cutting import load_piece, piece_words
    from softplc.machines.cutting.preview import preview
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

from softplc.machines.lazy import lazy_exports

# name -> the submodule that defines it, imported on first use (machines/lazy.py)
_EXPORTS = {
    "Arc": "geometry",
    "CoincidentPointsError": "geometry",
    "CuttingError": "geometry",
    "Fillet": "geometry",
    "FilletError": "geometry",
    "GeometryError": "geometry",
    "Line": "geometry",
    "LineSplit": "motion",
    "NewtonCurve": "geometry",
    "NewtonError": "geometry",
    "Piece": "piece",
    "PieceError": "piece",
    "Segment": "piece",
    "SegmentWords": "regmap",
    "Trapezoid": "motion",
    "ZeroRadiusError": "geometry",
    "fillet": "geometry",
    "load_piece": "load",
    "matlab_steps": "motion",
    "piece_from_dict": "piece",
    "piece_from_gcode": "piece",
    "piece_words": "regmap",
    "segment_words": "regmap",
    "split_line": "motion",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
