"""The servo axis's status words (offsets Word.ACTUAL.. of its block): the bits of `St` and
the positions, errors and signals of the last servo tick, written in one `pack_into`.

`SOURCE` is the one description of the bits and the write, over plain names: here it is
compiled with a prologue reading them from the axis (`StatusWords`, every state); the
servo loop's generated scan (`loop.py`) runs it on the locals it already holds."""

from __future__ import annotations

import struct
from math import floor
from typing import TYPE_CHECKING, Any

from softplc.devices.axis.options import Err, St, Word

if TYPE_CHECKING:
    from softplc.devices.axis.state import ServoState

# The status words in word order, (offset, struct code): one `pack_into` writes them all.
_STATUS_WORDS = ((Word.ACTUAL, "i"), (Word.COMMANDED, "i"), (Word.FE, "f"), (Word.FE_MAX, "f"),
                 (Word.STATUS, "H"), (Word.ERROR, "H"), (Word.TICKS, "i"), (Word.OUTPUT, "f"),
                 (Word.CURRENT, "f"), (Word.VELOCITY, "f"))
_STATUS_PACK = struct.Struct("=" + "".join(c for _, c in _STATUS_WORDS)).pack_into
assert [o for o, _ in _STATUS_WORDS] == [  # contiguous, from ACTUAL to the block's end
    Word.ACTUAL + sum(struct.calcsize(c) // 2 for _, c in _STATUS_WORDS[:i])
    for i in range(len(_STATUS_WORDS))] and Word.VELOCITY + 2 == Word.SIZE

# The names SOURCE reads besides the state: the bits and codes as constants (a global is
# cheaper than St.X), the pack.
NAMESPACE: dict[str, Any] = {
    **{f"_{name}": getattr(St, name) for name in (
        "ENABLED", "BUSY", "IN_POSITION", "DONE", "HOMED", "FE_WARNING", "FE_FATAL",
        "AMP_FAULT", "LIMIT_PLUS", "LIMIT_MINUS", "ESTOP", "ERROR", "HOMING", "OPEN_LOOP")},
    "_FATAL_ERRORS": (Err.FATAL_FE, Err.LIMIT, Err.NOT_HOMED), "_AMP": Err.AMP_FAULT,
    "_ENABLED_BUSY": St.ENABLED | St.BUSY,
    "_pack": _STATUS_PACK, "_pack_ticks": struct.Struct("=i").pack_into, "floor": floor}
TICKS_AT = 2 * (Word.TICKS - Word.ACTUAL)  # byte offsets from the first status word
END_AT = 2 * (Word.SIZE - Word.ACTUAL)

# In: closed, open_loop, coast, homing, ntraj (trajectory samples), tail_v, done, homed,
# warn, fe, fe_max, err, latched, ready, x, ap (raw encoder count), cp, origin, k, u, w,
# vel, dev, and the axis's constants in_pos, lp, lm, cur_scale, buf, at. SLOW gives the
# bits that change only with a command, an event or the end of a trajectory (`slow`, kept
# as `dev._st_slow`: the generated scan of a moving axis starts from it); FAST adds those
# of every tick: s, the bits. PACK writes them with every status word (its 'f' rounds to
# single precision as the memory image's %MF casts do; native order).
SLOW = """\
busy = homing != 0 or ntraj != 0 or tail_v != 0.0 or coast or open_loop
slow = (_ENABLED if closed else 0) | (_BUSY if busy else 0) | (_DONE if done else 0) \\
    | (_HOMED if homed else 0) | (_HOMING if homing else 0) \\
    | (_OPEN_LOOP if open_loop else 0)
if err:
    slow |= _ERROR
    if latched and err in _FATAL_ERRORS:
        slow |= _FE_FATAL
if err == _AMP or not ready:
    slow |= _AMP_FAULT
    if dev.estop_active():
        slow |= _ESTOP
dev._st_slow = slow
"""
FAST = """\
s = (slow | _FE_WARNING) if warn else slow
if slow & _ENABLED_BUSY == _ENABLED and (fe if fe >= 0 else -fe) <= in_pos:
    s |= _IN_POSITION
if x >= lp:
    s |= _LIMIT_PLUS
elif x <= lm:
    s |= _LIMIT_MINUS
"""
SOURCE = SLOW + FAST
PACK = """\
_pack(buf, at, round(ap - origin), round(cp - origin), fe if closed else 0.0, fe_max, s, err,
      k & 0x7FFFFFFF, u, w * cur_scale, vel)
"""

_PROLOGUE = """\
    closed, open_loop, coast, homing = dev.closed_, dev.open_loop_, dev._coast_, dev.homing_
    ntraj, tail_v, done, homed, warn = len(dev._traj_), dev._tail_v_, dev.done_, dev.homed_, \\
        dev.warn_
    fe, fe_max, err, latched, ready = dev.fe_, dev.fe_max_, dev.error_, dev.latched_, dev._ready_
    x, cp, origin, k, u, w, vel = dev.x_, dev._cp_, dev.origin_, dev.k, dev.u_, dev.w_, dev._vel_
    ap = x - dev._start if dev._ideal else floor(x) - dev._enc0  # (_raw() inlined)
    in_pos, lp, lm, cur_scale = dev._in_pos, dev._lp, dev._lm, dev._cur_scale
    buf, at = dev._buf, dev._status_at
"""


def indent(source: str, by: str = "    ") -> str:
    return "".join(f"{by}{line}\n" for line in source.splitlines())


def _generic(name: str, source: str) -> Any:
    """`name(dev) -> bits` over any state of the axis, from the description above."""
    ns = dict(NAMESPACE)
    code = f"def {name}(dev):\n{_PROLOGUE}{indent(source)}    return s\n"
    exec(compile(code, "<servo status>", "exec"), ns)  # noqa: S102 (our own source)
    return ns[name]


_bits, _write = _generic("bits", SOURCE), _generic("write", SOURCE + PACK)


class StatusWords:
    def __init__(self, axis: ServoState):
        self.a = axis

    def bits(self) -> int:
        """The status bits (class St) of the last servo tick."""
        return _bits(self.a)

    def write(self) -> None:
        """The status bits, then every status word in one `pack_into`."""
        _write(self.a)
