"""The I-variables of a running servo axis: read and written while it runs (PMAC's `I130 =
8000` typed at the terminal, or PMACTuningPro's gain boxes), from Python, from Modbus words
or from `softplc servo set/get`.

A change is checked at once (the same bounds as the TOML table's; `Ixx60`, the servo rate,
is configuration only) and applied at a servo tick in the device's next scan: with the
loop closed its first tick still runs the old gains, and the new ones act from the second.
It is bumpless: the integrator takes the difference between the old law's output and the
new law's on that first tick's terms (FE, CV, CA, IE, AV), so the output the DAC holds
does not jump. With Ixx33 = 0 there is no integrator to take it, and the
output follows the new law from the next tick [choice: PMAC itself is not bumpless].

Word table (option `ivar_words`, a %MW address; the servo table page's word map):

    +0  %MW  the I-variable number (xx) of the last write refused, 0 = none (device)
    +1  %MW  changes applied (device; wraps at 65536)
    +2  %MF  load disturbance, DAC bits (a step of load torque; 0 = none)
    +4  %MF  the first I-variable of `IVARS` (Ixx08), then one %MF per row in its order

A host writes a %MF; the device reads the table every scan, applies what changed, and
writes back the value in force (the old one when refused). A cold start clears %MW: the
device writes the table again at once (`Device.cold_start`), so a host's write landing
before its next scan is the only change seen; a table found all zero otherwise (a memory
image restored cleared) is written again, not applied.
"""

from __future__ import annotations

import math
import struct
from functools import partial
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from softplc.devices.axis.law import IVARS, Coefficients, Gains, law_output
from softplc.errors import SoftPLCError

if TYPE_CHECKING:
    from softplc.devices.axis.state import ServoState

REFUSED, APPLIED, DISTURBANCE, FIRST = 0, 1, 2, 4
SIZE = FIRST + 2 * len(IVARS)
CONFIG_ONLY = {"Ixx60"}  # the servo rate: fixed once the device is built
_NAMES = {**{i: (i, n) for i, n, _, _ in IVARS}, **{n: (i, n) for i, n, _, _ in IVARS}}
_FLOATS = struct.Struct("=" + "f" * (SIZE // 2 - 1))


class IVarError(SoftPLCError):
    """An I-variable that does not exist, is not settable at run time, or a bad value."""


def resolve(name: str) -> tuple[str, str]:
    """`Ixx30`, `kp` (or `I30`) -> ("Ixx30", "kp")."""
    key = name.strip()
    if key[:1] in "Ii" and key[1:].isdigit():
        key = f"Ixx{int(key[1:]):02d}"
    elif key[:3].lower() == "ixx":
        key = "Ixx" + key[3:]
    if key not in _NAMES:
        raise IVarError(f"unknown I-variable {name!r} (known: "
                        + ", ".join(i for i, *_ in IVARS) + ")")
    return _NAMES[key]


#: a load disturbance step, DAC bits at most (the DAC's 16-bit span, `set_disturbance`)
DISTURBANCE_MAX = 32768


def disturbance_refusal(bits: Any) -> str | None:
    """Why `bits` is no load disturbance (None: it is one)."""
    if not isinstance(bits, int | float) or not math.isfinite(bits) \
            or abs(bits) > DISTURBANCE_MAX:
        return f"disturbance {bits!r}: expected DAC bits within +-{DISTURBANCE_MAX}"
    return None


def check(gains: Any, name: str, value: float) -> Any:
    """The gains with `name` set to `value`, validated as the TOML table is."""
    ivar, plain = resolve(name)
    if ivar in CONFIG_ONLY:
        raise IVarError(f"{ivar} ({plain}) is set in the configuration only")
    if not isinstance(value, int | float) or not math.isfinite(value):
        raise IVarError(f"{ivar} ({plain}): {value!r} is not a finite number")
    data = gains.model_dump()
    data[plain] = int(value) if isinstance(data[plain], int) and value == int(value) \
        else value
    try:
        return Gains.model_validate(data)
    except ValidationError as e:
        why = "; ".join(err["msg"] for err in e.errors())
        raise IVarError(f"{ivar} ({plain}) = {value:g}: {why}") from None


class IVarTable:
    def __init__(self, axis: ServoState):
        self.a = axis
        self._pending: Any = None  # gains checked, waiting for the next scan's tick
        self._at: int | None = None  # word index of the table
        self.lo = self.hi = 0
        self.seen = b""  # the values' bytes as last written: a difference is a host's write
        self.applied = 0  # changes applied (the table's APPLIED word)

    # -- the device's WordCheck: a host's value refused before it is queued ------------
    def ranges(self) -> list[tuple[int, int]]:
        at = self._at
        return [] if at is None else [(at + DISTURBANCE, at + SIZE)]

    def refusal(self, kind: str, index: int, value: float) -> str | None:
        """Why the table refuses `value` written to %MF`index` (the check `set` and a
        host's write make: `check`, the law's ranges), None if it takes it or `index` is
        no value of the table."""
        at = self._at
        if at is None or kind != "MF":
            return None
        off = index - at
        why = None
        if off == DISTURBANCE:
            why = disturbance_refusal(value)
        elif FIRST <= off < SIZE and (off - FIRST) % 2 == 0:
            try:
                check(self._pending or self.a.gains, IVARS[(off - FIRST) // 2][0], value)
            except IVarError as e:
                why = str(e)
        return f"device {self.a.name!r}: {why}" if why else None

    def get(self, name: str) -> float:
        return getattr(self.a.gains, resolve(name)[1])

    def set(self, name: str, value: float) -> None:
        """Check now (IVarError), apply at a servo tick of the device's next scan."""
        self._pending = check(self._pending or self.a.gains, name, value)
        self.a._watch = True
        self.a._ivars_clean = _false  # the next scan applies it

    def poll(self, due: int) -> None:
        """Once per scan while watched, before its cycles (`due`: the cycle count due by
        the scan's end): a host's writes, then the changes waiting."""
        if not self.a._buf.startswith(self.seen, self.lo):
            self.scan()
        if self._pending is not None:
            self.apply(due)

    def apply(self, due: int) -> None:
        """The pending gains, bumplessly: with the loop closed, the first cycle due runs
        with the old gains keeping its terms, and the new gains act from the next."""
        a, new = self.a, self._pending
        if a.closed and due <= a.k:
            return  # no tick due in this scan (scans faster than the servo): the next
        self._pending = None
        a._watch = self._at is not None
        self._watch_table()
        if new is None or new == a.gains:
            return
        captured = a.closed
        if captured:
            a.runner.cycles(1, capture=True)
        old_c, old_g = a.coef, a.gains
        c = Coefficients.of(new)
        if captured and a.closed and c.ie:
            terms = (a.fe, a._cvp, a._ca, a._ie, a._av)
            ie = a._ie + (law_output(old_c, old_g, *terms) - law_output(c, new, *terms)) / c.ie
            lim = new.int_limit / 16 if new.int_limit else math.inf
            a._ie = max(-lim, min(lim, ie))
        a.gains, a.coef = new, c
        a.runner.build()
        self.applied += 1
        self.write_words()

    # -- the Modbus word table ------------------------------------------------------------------
    def bind(self, index: int) -> None:
        self._at = index
        self.a._watch = True
        self.lo, self.hi = 2 * (index + DISTURBANCE), 2 * (index + SIZE)  # bytes of the values
        self.write_words()

    def scan(self) -> None:
        """What a host wrote into the table (the device calls it when `seen` differs)."""
        at = self._at
        if at is None:
            return
        now = bytes(self.a._buf[self.lo:self.hi])
        if now == self.seen:
            return
        if not any(now):  # the image was cleared (a cold start), no host wrote: refill
            self.write_words()
            return
        vals = _FLOATS.unpack(now)
        old = _FLOATS.unpack(self.seen)
        mw = self.a._mem.mw  # type: ignore[union-attr]
        mw.uw[at + REFUSED] = 0  # this scan's writes decide it
        if vals[0] != old[0]:
            try:
                self.a.set_disturbance(vals[0])
            except SoftPLCError:
                mw.uw[at + REFUSED] = 0xFFFF
        for (ivar, _, _, _), v, was in zip(IVARS, vals[1:], old[1:], strict=True):
            if v != was:
                try:
                    self.set(ivar, v)
                except IVarError:
                    mw.uw[at + REFUSED] = int(ivar[3:])
        self.write_words()

    def write_words(self) -> None:
        """The values in force (or accepted and waiting for a tick) into the table
        (float32, as every %MF)."""
        at = self._at
        if at is None:
            return
        a = self.a
        g = self._pending or a.gains
        vals = [a.disturbance, *(float(getattr(g, n)) for _, n, _, _ in IVARS)]
        _FLOATS.pack_into(a._buf, 2 * (at + DISTURBANCE), *vals)
        a._mem.mw.uw[at + APPLIED] = self.applied & 0xFFFF  # type: ignore[union-attr]
        self.seen = bytes(a._buf[self.lo:self.hi])
        self._watch_table()

    def _watch_table(self) -> None:
        """The device's per-scan test: the table as last written (no host wrote)."""
        if self._pending is None:
            self.a._ivars_clean = partial(self.a._buf.startswith, self.seen, self.lo)


def _false() -> bool:
    return False
