"""The servo axis's status words (offsets Word.ACTUAL.. of its block): the bits of `St` and
the positions, errors and signals of the last servo tick, written in one `pack_into`."""

from __future__ import annotations

import struct
from math import floor
from typing import TYPE_CHECKING

from .options import Err, St, Word

if TYPE_CHECKING:
    from .servo import ServoAxis

# The status words in word order, (offset, struct code): one `pack_into` writes them all.
_STATUS_WORDS = ((Word.ACTUAL, "i"), (Word.COMMANDED, "i"), (Word.FE, "f"), (Word.FE_MAX, "f"),
                 (Word.STATUS, "H"), (Word.ERROR, "H"), (Word.TICKS, "i"), (Word.OUTPUT, "f"),
                 (Word.CURRENT, "f"), (Word.VELOCITY, "f"))
_STATUS_PACK = struct.Struct("=" + "".join(c for _, c in _STATUS_WORDS)).pack_into
assert [o for o, _ in _STATUS_WORDS] == [  # contiguous, from ACTUAL to the block's end
    Word.ACTUAL + sum(struct.calcsize(c) // 2 for _, c in _STATUS_WORDS[:i])
    for i in range(len(_STATUS_WORDS))] and Word.VELOCITY + 2 == Word.SIZE

# The bits as module constants: read every scan, a global is cheaper than St.X.
_ENABLED, _BUSY, _IN_POSITION, _DONE, _HOMED, _FE_WARNING, _HOMING, _OPEN_LOOP = (
    St.ENABLED, St.BUSY, St.IN_POSITION, St.DONE, St.HOMED, St.FE_WARNING, St.HOMING,
    St.OPEN_LOOP)
_LIMIT_PLUS, _LIMIT_MINUS = St.LIMIT_PLUS, St.LIMIT_MINUS


class StatusWords:
    def __init__(self, axis: ServoAxis):
        self.a = axis

    def bits(self) -> int:
        """The status bits (class St) of the last servo tick."""
        a = self.a
        busy = a.homing != 0 or bool(a._traj) or a._tail_v != 0.0 or a._coast or a.open_loop
        closed = a.closed
        s = (_ENABLED if closed else 0) | (_BUSY if busy else 0) \
            | (_DONE if a.done else 0) | (_HOMED if a.homed else 0) \
            | (_FE_WARNING if a.warn else 0) | (_HOMING if a.homing else 0) \
            | (_OPEN_LOOP if a.open_loop else 0)
        if closed and not busy and abs(a.fe) <= a._in_pos:
            s |= _IN_POSITION
        err = a.error
        if err:
            s |= St.ERROR
            if a.latched and err in (Err.FATAL_FE, Err.LIMIT, Err.NOT_HOMED):
                s |= St.FE_FATAL
        if err == Err.AMP_FAULT or not a._ready:
            s |= St.AMP_FAULT
            if a.estop_active():
                s |= St.ESTOP
        x = a.x
        if x >= a._lp:
            s |= _LIMIT_PLUS
        elif x <= a._lm:
            s |= _LIMIT_MINUS
        return s

    def write(self) -> None:
        """The status bits, then every status word in one `pack_into` (its 'f' rounds to
        single precision as the memory image's %MF casts do; native order)."""
        a = self.a
        s = self.bits()
        x, closed, err = a.x, a.closed, a.error
        origin = a.origin
        _STATUS_PACK(a._buf, a._status_at,
                     round((x - a._start if a._ideal else floor(x) - a._enc0)
                           - origin),  # _raw() inlined
                     round(a._cp - origin), a.fe if closed else 0.0, a.fe_max, s, err,
                     a.k & 0x7FFFFFFF, a.u, a.w * a._cur_scale, a._vel)
