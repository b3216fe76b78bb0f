"""The Twido memory image.

Words: each word family (%MW, %KW, %SW) is one `bytearray`. Compiled rungs, the Modbus
map and snapshots index `memoryview` casts of it. `%MDi`/`%MFi` overlay `%MWi` (low word) and
`%MWi+1` (high word): they are 32-bit casts of the word buffer at an even or an odd word
offset, so a write through one view is seen by all the others with no copying.

Bits (%I, %Q, %M, %S, %X) are plain Python lists of bools: CPython specialises list
indexing, and boolean rungs run 3.3x faster over lists than over a bytearray (3.3 vs
10.9 ns per instruction on the generated 1,000-instruction program, this machine). Every
writer stores True/False, never 1/0: a conditional jump on a bool skips the truth test
of an int (about -20 % on that program's main()). Reads users see convert (`read`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from softplc.errors import AddressError
from softplc.twido import catalog
from softplc.twido.address import (
    ANALOG_STRIDE,
    BLOCK_FIELDS,
    IO_KINDS,
    LINK_STATIONS,
    LINK_WORDS,
    WIDTH,
    Ref,
    parse_address,
)
from softplc.twido.numeric import to_f32, wrap16, wrap32
from softplc.twido.profile import DEFAULT_PROFILE, Profile

# the word families a snapshot holds
WORD_IMAGES = ("mw", "kw", "sw", "iw", "qw", "inw", "qnw")


class WordFamily:
    """A run of 16-bit words with 32-bit integer and float overlays (e.g. %MW/%MD/%MF)."""

    def __init__(self, n: int):
        self.n = n
        self.buf = bytearray(2 * n)
        mv = memoryview(self.buf)
        self.w = mv.cast("h")  # signed 16-bit words
        self.uw = mv.cast("H")  # the same words, unsigned (Modbus)
        n_even, n_odd = n // 2, (n - 1) // 2
        # index i of a 32-bit object -> (view, i >> 1): even i in the first, odd in the second
        self.d = (mv[: 4 * n_even].cast("i"), mv[2 : 2 + 4 * n_odd].cast("i"))
        self.f = (mv[: 4 * n_even].cast("f"), mv[2 : 2 + 4 * n_odd].cast("f"))

    def get_d(self, i: int) -> int:
        return self.d[i & 1][i >> 1]

    def set_d(self, i: int, v: int) -> None:
        self.d[i & 1][i >> 1] = wrap32(v)

    def get_f(self, i: int) -> float:
        return self.f[i & 1][i >> 1]

    def set_f(self, i: int, v: float) -> None:
        self.f[i & 1][i >> 1] = to_f32(v)


class MemoryImage:
    """All PLC data: bits, words, I/O images, system objects and function blocks."""

    def __init__(self, profile: Profile = DEFAULT_PROFILE):
        self.profile = profile
        c = profile.count
        self.stride = profile.channels_per_module
        # the base, the expansion slots, then the base I/O of the remote I/O controllers
        # on the Remote Link (%Ix.0.z, address.remote_io_slot)
        n_io = (profile.expansion_slots + LINK_STATIONS) * self.stride
        # Input/output images and what the field (devices, API) sees. Inputs are copied
        # field -> image at the start of a scan, outputs image -> field at its end.
        self.i = [False] * n_io
        self.i_field = [False] * n_io
        self.q = [False] * n_io
        self.q_field = [False] * n_io
        # The scan-boundary copies (field -> input image, output image -> field) cover the
        # channels in use only: those the program, the configuration, a device or an API
        # write names (`use_io`). They are generated straight-line code, rebuilt when the
        # set grows: a list slice of one 32-channel module costs more than the whole
        # drawing-table program's I/O.
        self._in_used: set[int] = set()
        self._out_used: set[int] = set()
        # called when the copies change: the engine inlines them in its generated scan
        self.on_copiers: Callable[[], None] | None = None
        self._build_copiers()
        self.m = [False] * c("M")
        self.s = [False] * c("S")
        self.x = [False] * c("X")
        self.mw = WordFamily(c("MW"))
        self.kw = WordFamily(c("KW"))
        self.sw = WordFamily(c("SW"))
        # Analog I/O words %IWm.c / %QWm.c: devices and the API write %IW between scans,
        # the program writes %QW; no scan-boundary copy (an analog module converts on its
        # own, asynchronously to the scan).
        n_aio = (profile.expansion_slots + 1) * ANALOG_STRIDE
        self.iw = WordFamily(n_aio)
        self.qw = WordFamily(n_aio)
        # Remote Link network words %INWi.j (received) / %QNWi.j (sent): the link's exchange
        # writes %INW and reads %QNW on its own cycle (runtime/remotelink.py)
        self.inw = WordFamily(LINK_STATIONS * LINK_WORDS)
        self.qnw = WordFamily(LINK_STATIONS * LINK_WORDS)
        self.analog: Any = None  # the AnalogIO converter, when analog channels are configured
        self.pulses: Any = None  # runtime.pulse.PulseOutputs, when %PLS/%PWM are configured
        # fast counters: the CountingInputs that pulse sources feed (runtime/fastcount.py)
        self.counting: Any = None
        # Function blocks, filled in by the engine from the configuration.
        self.blocks: dict[str, dict[int, Any]] = {k: {} for k in catalog.FAMILIES}

    # -- address resolution ---------------------------------------------------------------
    def ref(self, address: str | Ref) -> Ref:
        return address if isinstance(address, Ref) else parse_address(address, self.profile)

    def bits(self, kind: str) -> list[bool]:
        return {"I": self.i, "Q": self.q, "M": self.m, "S": self.s, "X": self.x}[kind]

    def words(self, kind: str) -> WordFamily:
        return {"MW": self.mw, "MD": self.mw, "MF": self.mw, "KW": self.kw,
                "KD": self.kw, "KF": self.kw, "SW": self.sw, "IW": self.iw, "QW": self.qw,
                "INW": self.inw, "QNW": self.qnw}[kind]

    def block(self, ref: Ref) -> Any:
        try:
            return self.blocks[ref.kind][ref.index]
        except KeyError:
            raise AddressError(f"{ref.label + ': ' if ref.symbol else ''}%{ref.kind}{ref.index} "
                               f"is not configured") from None

    def _effective_index(self, ref: Ref) -> int:
        idx = ref.index
        if ref.offset is not None:
            idx += self.mw.w[ref.offset.index]
        return idx

    # -- generic (slow path) access for tools, the API and the debugger --------------------
    def read(self, address: str | Ref) -> Any:
        """Read any object: bool for bits, int for words, float for %MF/%KF, list for tables."""
        ref = self.ref(address)
        if ref.kind in BLOCK_FIELDS:
            b = self.block(ref)
            if ref.field is None:
                return b
            if ref.field == "J":
                return bool(b.bit(ref.bit))
            v = getattr(b, ref.field)
            return bool(v) if BLOCK_FIELDS[ref.kind][ref.field][0] == "bool" else int(v)
        if ref.length is not None:
            step = WIDTH.get(ref.kind, 1)
            return [self.read(Ref(ref.kind, ref.index + k * step)) for k in range(ref.length)]
        idx = self._effective_index(ref)
        if ref.kind == "I" and idx not in self._in_used:
            return bool(self.i_field[idx])  # not latched: what a latch would copy
        if ref.kind in IO_KINDS or ref.kind in ("M", "S", "X"):
            return bool(self.bits(ref.kind)[idx])
        fam = self.words(ref.kind)
        if ref.bit is not None:
            return bool((fam.w[idx] >> ref.bit) & 1)
        if ref.kind in ("MD", "KD"):
            return fam.get_d(idx)
        if ref.kind in ("MF", "KF"):
            return fam.get_f(idx)
        return fam.w[idx]

    def write(self, address: str | Ref, value: Any, *, field_inputs: bool = True) -> None:
        """Write any object. `%I` writes go to the field inputs (seen at the next scan)
        unless `field_inputs` is False. No read-only check: that is the caller's policy."""
        ref = self.ref(address)
        if ref.kind in BLOCK_FIELDS:
            b = self.block(ref)
            if ref.field == "J":  # %SBRi.j, %SCi.j
                b.set_bit(ref.bit, value)
                return
            if ref.field is None or ref.field == "J":
                raise AddressError(f"{ref.label} cannot be written")
            v = int(value)
            if BLOCK_FIELDS[ref.kind][ref.field][0] == "int16":
                v = wrap16(v)  # a word (%VFCi.S0 := 40000 from the API is 16#9C40)
            setattr(b, ref.field, v)
            return
        if ref.length is not None:
            step = WIDTH.get(ref.kind, 1)
            for k, v in enumerate(value):
                self.write(Ref(ref.kind, ref.index + k * step), v, field_inputs=field_inputs)
            return
        idx = self._effective_index(ref)
        if ref.kind in IO_KINDS:
            self.use_io(ref)
        if ref.kind == "I" and field_inputs:
            self.i_field[idx] = bool(value)
            return
        if ref.kind in IO_KINDS or ref.kind in ("M", "S", "X"):
            self.bits(ref.kind)[idx] = bool(value)
            return
        fam = self.words(ref.kind)
        if ref.bit is not None:
            w = fam.uw[idx]
            fam.uw[idx] = (w | (1 << ref.bit)) if value else (w & ~(1 << ref.bit) & 0xFFFF)
        elif ref.kind in ("MD", "KD"):
            fam.set_d(idx, int(value))
        elif ref.kind in ("MF", "KF"):
            fam.set_f(idx, float(value))
        else:
            fam.w[idx] = wrap16(int(value))

    # -- scan boundary ----------------------------------------------------------------------
    def use_io(self, ref: Ref) -> None:
        """Make sure the scan-boundary copies cover an I/O address (or bit string)."""
        used = self._in_used if ref.kind == "I" else self._out_used
        new = set(range(ref.index, ref.index + (ref.length or 1))) - used
        if new:
            used |= new
            self._build_copiers()

    def io_used(self, kind: str) -> frozenset[int]:
        """Flat indexes of the %I or %Q channels in use (named by the program, the
        configuration, a device or an API write)."""
        return frozenset(self._in_used if kind == "I" else self._out_used)

    def copy_lines(self, kind: str) -> list[str]:
        """The scan-boundary copy of "I" (`i[k] = i_field[k]`) or "Q" (`q_field[k] = q[k]`)
        as lines of Python, one per channel in use."""
        dst, src, used = ("i", "i_field", self._in_used) if kind == "I" else \
            ("q_field", "q", self._out_used)
        return [f"{dst}[{k}] = {src}[{k}]" for k in sorted(used)]

    def _build_copiers(self) -> None:
        def copier(name: str, kind: str, dst: str, src: str) -> object:
            body = "".join(f"    {x}\n" for x in self.copy_lines(kind)) or "    pass\n"
            ns = {dst: getattr(self, dst), src: getattr(self, src)}
            exec(f"def {name}({dst}={dst}, {src}={src}):\n{body}", ns)
            return ns[name]

        self.latch_inputs = copier("latch_inputs", "I", "i", "i_field")
        self.publish_outputs = copier("publish_outputs", "Q", "q_field", "q")
        if self.on_copiers is not None:
            self.on_copiers()

    # -- snapshots (debugger history, retained state) -------------------------------------
    def snapshot(self) -> dict[str, Any]:
        snap: dict[str, Any] = {
            name: bytes(getattr(self, name))
            for name in ("i", "i_field", "q", "q_field", "m", "s", "x")
        }
        for name in WORD_IMAGES:
            snap[name] = bytes(getattr(self, name).buf)
        snap["blocks"] = {k: {i: b.state() for i, b in d.items()} for k, d in self.blocks.items()}
        return snap

    def restore(self, snap: dict[str, Any]) -> None:
        for name in ("i", "i_field", "q", "q_field", "m", "s", "x"):
            getattr(self, name)[:] = map(bool, snap[name])
        for name in WORD_IMAGES:
            if name in snap:
                getattr(self, name).buf[:] = snap[name]
        for k, d in snap["blocks"].items():
            for i, st in d.items():
                if i in self.blocks[k]:
                    self.blocks[k][i].set_state(st)
