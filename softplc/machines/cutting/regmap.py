"""The cutting table's segment words: what the host writes to the PLC for each segment.

The segment words of docs/machines/cutting-table.md ("Segment words") [choice]; holding register
n is %MWn; %MD/%MF take two registers, low word first (docs/twido.md#memory-objects):

| word | name | by | meaning |
|---|---|---|---|
| %MD100, %MD102 | SEG_X, SEG_Y | host | segment end, µm (work coordinates) |
| %MF104 | SEG_V | host | path speed mm/s (0 = the program's default); dwell: seconds |
| %MW106 | SEG_KIND | host | 1 cut, 2 move (torch off), 3 cut chained, 4/5 dwell (below) |
| %MW107 | SEG_NO | host | sequence number, 1..32767 then 1 again |
| %MW108 | INICIO | host / PLC | host writes 1; the PLC: 0 accepted, -1 refused (FAULT) |
| %MW109 | EJECUTANDO | PLC | 1 from acceptance until both axes are in position |
| %MW110 | FAULT | PLC | see FAULTS |
| %MD112, %MD114 | pos_X, pos_Y | PLC | actual positions, µm |
| %MW128 | SEG_DONE | PLC | last completed SEG_NO |

One FC 16 frame of `FRAME_LEN` registers from SEG_BASE carries a whole segment (INICIO
last), so the PLC, which applies one frame whole at a scan start, never sees half of one.
The streaming client (`client.py`) and the in-process feeder use these words.

Kind 3, "cut chained", is the host's look-ahead [choice]: a cut whose next segment is a
cut too. Between two cuts the PLC keeps the torch lit through the one READY scan (one
pierce per contour, not one per chord). With kind 1 it can do so only when the next cut
is already in its queue, which depends on how fast the host answered; with kind 3 it
knows, whatever the host's timing, so a run's torch trace does not depend on the host's
speed. `piece_words` gives every segment of a piece its kind this way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from softplc.machines.cutting.piece import CUT, DWELL, Segment
from softplc.machines.gcode.parser import steps_of
from softplc.modbus_codec import float_to_words, long_to_words

SEG_BASE = 100
SEG_X, SEG_Y, SEG_V, SEG_KIND, SEG_NO, INICIO = 100, 102, 104, 106, 107, 108
EJECUTANDO, FAULT, STATE = 109, 110, 111
POS_X, POS_Y, SEG_DONE = 112, 114, 128
FRAME_LEN = INICIO - SEG_BASE + 1
KIND_CODE = {"cut": 1, "move": 2}
#: a cut followed by a cut (the host's look-ahead: the torch stays lit between them)
KIND_CUT_CHAINED = 3
#: a dwell with the torch lit (a cut follows) or off
KIND_DWELL_LIT, KIND_DWELL_OFF = 4, 5
START_VALUE = 1
#: INICIO's answer to a frame offered while the PLC is in FAULT: refused, never run (not
#: even after RESET); the mailbox is free again for the host's next frame.
REFUSED = -1
#: SEG_NO wraps within a positive 16-bit word and is never 0 (0 = none done yet).
SEG_NO_MODULO = 32767
UM_PER_MM = 1000.0
FAULTS = {0: "none", 1: "limit switch", 2: "homing failed",
          3: "target outside the work area", 4: "axis error", 5: "E-stop",
          6: "bad segment (unknown kind, negative speed, dwell over 9.999 s)"}


def to_um(mm: float) -> int:
    """A coordinate in whole µm, rounded to nearest (the thesis truncates, B9)."""
    return steps_of(mm, UM_PER_MM)


def seg_no(number: int) -> int:
    return (number - 1) % SEG_NO_MODULO + 1


@dataclass(frozen=True)
class SegmentWords:
    """The values of one segment as the PLC receives them."""

    x_um: int
    y_um: int
    speed: float
    kind: int
    number: int

    def frame(self) -> list[int]:
        """The FC 16 registers from %MW100 (INICIO = 1 last)."""
        return [*long_to_words(self.x_um), *long_to_words(self.y_um), *float_to_words(self.speed),
                self.kind, self.number, START_VALUE]


def segment_words(seg: Segment, lit_next: bool = False) -> SegmentWords:
    """The words of `seg`; `lit_next`: the torch burns in the next segment (a cut, or a
    dwell before a cut), so a cut is chained (kind 3) and a dwell lit (kind 4)."""
    if seg.kind == DWELL:
        kind = KIND_DWELL_LIT if lit_next else KIND_DWELL_OFF
        return SegmentWords(to_um(seg.end[0]), to_um(seg.end[1]), seg.dwell, kind,
                            seg_no(seg.number))
    if seg.kind != CUT:
        kind = KIND_CODE["move"]
    else:
        kind = KIND_CUT_CHAINED if lit_next else KIND_CODE["cut"]
    return SegmentWords(to_um(seg.end[0]), to_um(seg.end[1]), seg.speed, kind,
                        seg_no(seg.number))


def piece_words(segs: Sequence[Segment]) -> list[SegmentWords]:
    """The words of consecutive segments, each with the look-ahead of what follows: the
    torch burns in a segment that is a cut, or a dwell whose next motion is a cut."""
    lit = [False] * (len(segs) + 1)
    for i in range(len(segs) - 1, -1, -1):
        lit[i] = segs[i].kind == CUT or (segs[i].kind == DWELL and lit[i + 1])
    return [segment_words(s, lit[i + 1]) for i, s in enumerate(segs)]
