"""Fast counters %FCi and very fast counters %VFCi, counting pulses between scans.

A pulse input at kHz rates changes many times inside one scan: a counter that sampled %I
at the scan would miss most edges. On the controller the counting inputs are read by
hardware; here the simulated source (a device such as `devices/encoder.py`) tells the
counter how many counting edges it produced, in small time steps, through
`CountingInputs.feed` (`mem.counting`, present when a counter is configured). The source
still writes the input's level into %I, so the program and the monitor see the level.
Devices -> runtime: this module knows no device.

[manual, from memory of TWD USE 10AE (Twido software reference), "fast counter" and "very
fast counter" function blocks: not found in the search corpora; check on hardware]
  %FCi   IN = 1 counts the rising edges of its input; S = 1 initialises the value (up:
         0, down: %FCi.P) and clears %FCi.D. Up: when %FCi.V reaches %FCi.P, %FCi.D = 1
         and the value starts again from 0; down: when it reaches 0, %FCi.D = 1 and the
         value starts again from the preset. Values 0..65535 (a word).
  %VFCi  IN = 1 counts; S = 1 (or a rising edge on the preset input) loads the preset
         (up counting: 0). Modes: up, down, up/down (the direction input's level: 1 up),
         two-phase quadrature (phase B gives the direction), frequency meter (%VFCi.V =
         pulses per second over the time base %VFCi.T, 100 or 1000 ms). %VFCi.U the
         direction of the last count (1 up), %VFCi.F overflow (65535 -> 0 or 0 -> 65535),
         %VFCi.TH0 = (V >= %VFCi.S0), %VFCi.TH1 = (V >= %VFCi.S1), %VFCi.C the value
         captured on a rising edge of the catch input. Two reflex outputs, enabled by
         %VFCi.R (output 0) and %VFCi.S (output 1), take the state TwidoSuite's table gives
         them in each of the three zones V < S0, S0 <= V < S1, V >= S1.

Our choices: the reflex outputs are written the moment the counter's value enters another
zone, at the source's time step (`tick`, 1 ms by default), into the output image and the
field, independent of the scan; each change is logged (`CountingInputs.events`) with its
time. Above the input's highest frequency (profile: 5 kHz %FC, 20 kHz %VFC) the excess
edges are lost (counted in `.lost`), as an input filter that cannot follow would drop
them. The preset and catch inputs are sampled at every feed and at every scan start.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from softplc.runtime.blocks import Block
from softplc.twido.numeric import wrap16

MAX_COUNT = 65535  # 16-bit values [manual]
SPAN = MAX_COUNT + 1
FC_MODES = ("up", "down")
VFC_MODES = ("up", "down", "up_down", "quadrature", "frequency")
TIME_BASES_MS = (100, 1000)  # frequency meter [manual, from memory]
N_ZONES = 3  # V < S0, S0 <= V < S1, V >= S1
MASK = 0xFFFF
word = wrap16  # an unsigned count 0..65535 as the signed 16-bit word the program reads


class _PulseCounter(Block):
    """What both counters share: the enable (IN), the frequency limit, the input wiring."""

    PINS = ("IN", "S")

    def __init__(self, mode: str, preset: int, max_hz: float, modes: tuple[str, ...]):
        if mode not in modes:
            raise ValueError(f"mode {mode!r}: one of {', '.join(modes)}")
        if not 0 <= int(preset) <= MAX_COUNT:
            raise ValueError(f"preset {preset}: 0..{MAX_COUNT}")
        self.mode, self.max_hz = mode, max_hz
        # the words the program sees are signed 16-bit (V = 40000 reads as -25536, as a
        # %MW would); the counting uses them unsigned (& MASK)
        self.P = word(int(preset))
        self._en = 0
        self.lost = 0  # edges above the input's frequency limit
        self._credit = 0.0

    def _take(self, edges: int, dt: float) -> int:
        """How many of `edges` in `dt` seconds the input can follow (the rest is lost)."""
        rate = self.max_hz * dt
        self._credit = min(self._credit + rate, max(1.0, rate))
        n = min(edges, math.floor(self._credit + 1e-9))
        self._credit -= n
        self.lost += edges - n
        return n


class FastCounterConfig(BaseModel):
    """`[fast_counters."%FCi"]`, as TwidoSuite's fast counter screen: type and preset."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["up", "down"] = "up"
    preset: int = Field(MAX_COUNT, ge=0, le=MAX_COUNT)


class FastCounter(_PulseCounter):
    """%FCi, up or down counter on one base input."""

    FIELDS = ("V", "P", "D", "_en", "lost", "_credit")
    SUMMARY = ("V", "P", "D", "_en", "lost")  # the debugger's one-line summary

    def __init__(self, mode: str = "up", preset: int = MAX_COUNT, max_hz: float = 5_000.0):
        super().__init__(mode, preset, max_hz, FC_MODES)
        self.V = 0 if mode == "up" else self.P
        self.D = 0

    @classmethod
    def configured(cls, ctx: Any, hub: CountingInputs, ref: Any, o: FastCounterConfig,
                   where: str) -> FastCounter:
        """%FCi on its profile input (claimed: an input counts for one counter)."""
        wiring = ctx.profile.fast_counters[ref.index]
        c = cls(o.mode, o.preset, wiring.max_hz)
        hub.attach(c, ctx.claim_input(wiring.input, f"{where} (counting)"))
        return c

    def run(self, IN: Any = 0, S: Any = 0) -> None:
        self._en = 1 if IN else 0
        if S:
            self.V = 0 if self.mode == "up" else self.P
            self.D = 0

    def pulses(self, edges: int, direction: int, t: float, dt: float) -> None:
        n = self._take(edges, dt)
        if not self._en or not n:
            return
        preset = self.P & MASK
        p = preset or SPAN  # preset 0: a plain 16-bit counter (our choice)
        if self.mode == "up":
            v = (self.V & MASK) + n
            if v >= p:
                self.D = 1 if preset else self.D
                v %= p
        else:
            v = (self.V & MASK) - n
            if v <= 0:
                self.D = 1 if preset else self.D
                v = (v - 1) % p + 1 if preset else v % SPAN
        self.V = word(v)


class VeryFastCounterConfig(BaseModel):
    """`[very_fast_counters."%VFCi"]`: mode, preset, thresholds, the optional preset and
    catch inputs, the reflex outputs' state in the zones (V < S0, S0 <= V < S1, V >= S1),
    the frequency meter's time base."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["up", "down", "up_down", "quadrature", "frequency"] = "up"
    preset: int = Field(0, ge=0, le=MAX_COUNT)
    s0: int = Field(MAX_COUNT, ge=0, le=MAX_COUNT)
    s1: int = Field(MAX_COUNT, ge=0, le=MAX_COUNT)
    preset_input: bool = False
    catch_input: bool = False
    reflex0: list[Literal[0, 1]] | None = Field(None, min_length=N_ZONES, max_length=N_ZONES)
    reflex1: list[Literal[0, 1]] | None = Field(None, min_length=N_ZONES, max_length=N_ZONES)
    time_base: Literal["100ms", "1s"] = "1s"


class VeryFastCounter(_PulseCounter):
    """%VFCi: see the module docstring. `outputs`: the reflex outputs as (image, field,
    index) or None each; `zones`: per reflex output its state in the three zones."""

    # not `_zone`: the reflex outputs' cache, invalidated by set_state (a restored state
    # round-trips to the same snapshot)
    FIELDS = ("V", "P", "U", "C", "S0", "S1", "F", "TH0", "TH1", "R", "S", "T", "_en",
              "lost", "_credit", "_acc", "_acc_t", "_pre", "_cat")
    SUMMARY = ("V", "P", "U", "C", "S0", "S1", "TH0", "TH1", "F", "R", "S", "_en", "lost")

    def __init__(self, mode: str = "up", preset: int = 0, s0: int = MAX_COUNT,
                 s1: int = MAX_COUNT, max_hz: float = 20_000.0, time_base_ms: int = 1000,
                 zones: tuple[tuple[int, ...] | None, ...] = (None, None),
                 outputs: tuple[Any, ...] = (None, None), log: Any = None,
                 label: str = "%VFC"):
        super().__init__(mode, preset, max_hz, VFC_MODES)
        if time_base_ms not in TIME_BASES_MS:
            raise ValueError(f"time base {time_base_ms} ms: 100 or 1000")
        self.V = 0 if mode in ("up", "frequency") else self.P
        self.U, self.C, self.F, self.TH0, self.TH1 = 1, 0, 0, 0, 0
        self.S0, self.S1 = word(int(s0)), word(int(s1))
        self.R = self.S = 0  # reflex outputs enabled by the program [manual, from memory]
        self.T = time_base_ms
        # the reflex outputs are bit images: their levels as bools
        self.zones = tuple(None if z is None else tuple(map(bool, z)) for z in zones)
        self.outputs = outputs
        self.log = log  # (t, label, output index, value) appended on each reflex change
        self.label = label
        self._zone = -1
        self._acc, self._acc_t = 0, 0.0  # frequency meter: edges and time so far
        self._pre = self._cat = 0  # last levels of the preset and catch inputs
        self._thresholds()

    def _preset(self) -> None:
        self.V = 0 if self.mode in ("up", "frequency") else self.P
        self.F = 0

    def run(self, IN: Any = 0, S: Any = 0) -> None:
        self._en = 1 if IN else 0
        if S and self.mode != "frequency":
            self._preset()
        self._thresholds()

    def inputs(self, preset: int | None, catch: int | None, t: float) -> None:
        """Levels of the preset and catch inputs (None: not configured): act on edges."""
        if preset is not None:
            if preset and not self._pre and self.mode != "frequency":
                self._preset()
                self._thresholds(t)
            self._pre = preset
        if catch is not None:
            if catch and not self._cat:
                self.C = self.V
            self._cat = catch

    def pulses(self, edges: int, direction: int, t: float, dt: float) -> None:
        n = self._take(edges, dt)
        if not self._en:
            return
        if self.mode == "frequency":
            self._acc += n
            self._acc_t += dt
            if self._acc_t >= self.T / 1000 - 1e-9:
                self.V = word(min(MAX_COUNT, round(self._acc / self._acc_t)))
                self._acc, self._acc_t = 0, 0.0
                self._thresholds(t)
            return
        if not n:
            return
        d = n if self.mode == "up" else -n if self.mode == "down" else n * direction
        self.U = 1 if d > 0 else 0
        v = (self.V & MASK) + d
        if not 0 <= v <= MAX_COUNT:
            v %= SPAN
            self.F = 1
        self.V = word(v)
        self._thresholds(t)

    def _thresholds(self, t: float | None = None) -> None:
        v, s0, s1 = self.V & MASK, self.S0 & MASK, self.S1 & MASK
        self.TH0 = 1 if v >= s0 else 0
        self.TH1 = 1 if v >= s1 else 0
        zone = self.TH0 + self.TH1 if s0 <= s1 else (1 if self.TH0 else 0)
        key = zone * 4 + self.R * 2 + self.S  # an enable bit set by the program counts too
        if key == self._zone:
            return
        self._zone = key
        for k, (table, out, enabled) in enumerate(zip(self.zones, self.outputs,
                                                      (self.R, self.S), strict=True)):
            if table is None or out is None or not enabled:
                continue
            image, field, i = out
            value = table[zone]
            if field[i] != value or image[i] != value:
                image[i] = field[i] = value
                if self.log is not None and t is not None:
                    self.log.append((t, self.label, k, value))

    def set_state(self, d: dict[str, Any]) -> None:
        super().set_state(d)
        self._zone = -1  # rewrite the reflex outputs at the next change (restored image)


    @classmethod
    def configured(cls, ctx: Any, hub: CountingInputs, ref: Any, o: VeryFastCounterConfig,
                   where: str) -> VeryFastCounter:
        """%VFCi on its profile inputs and reflex outputs; the direction / phase B, preset
        and catch inputs claimed only when its mode or configuration uses them."""
        w, mem = ctx.profile.very_fast_counters[ref.index], ctx.mem
        outputs = tuple(None if z is None else (mem.q, mem.q_field, w.reflex[k])
                        for k, z in enumerate((o.reflex0, o.reflex1)))
        c = cls(o.mode, o.preset, o.s0, o.s1, w.max_hz, 100 if o.time_base == "100ms" else 1000,
                (o.reflex0 and tuple(o.reflex0), o.reflex1 and tuple(o.reflex1)), outputs,
                hub.events, str(ref))
        claim = ctx.claim_input
        two_inputs = o.mode in ("up_down", "quadrature")
        hub.attach(c, claim(w.pulse, f"{where} (pulses / phase A)"),
                   claim(w.direction, f"{where} (direction / phase B)") if two_inputs else None)
        hub.attach_vfc(c, claim(w.preset, f"{where} (preset input)") if o.preset_input else None,
                       claim(w.catch, f"{where} (catch input)") if o.catch_input else None)
        return c


class CountingInputs:
    """`mem.counting`: which counter listens to which base input, fed by the sources.

    `feed(input, edges, direction, t, dt)`: `edges` counting (rising) edges on the input
    (flat %I index) during the `dt` seconds ending at `t`; `direction` +1 / -1, or None when
    the counter should read its direction input's level. Listeners on other inputs of the
    same counter (preset, catch) are sampled first."""

    def __init__(self, i_field: list[bool]):
        self.i_field = i_field
        self.by_input: dict[int, list[tuple[Any, int | None]]] = {}  # -> (counter, dir input)
        self.vfc: list[tuple[VeryFastCounter, int | None, int | None]] = []
        # reflex output changes: (time s, "%VFCi", output 0/1, value), the latest 1024
        self.events: deque[tuple[float, str, int, int]] = deque(maxlen=1024)

    def attach(self, counter: Any, pulse_input: int, direction_input: int | None = None
               ) -> None:
        self.by_input.setdefault(pulse_input, []).append((counter, direction_input))

    def attach_vfc(self, counter: VeryFastCounter, preset: int | None,
                   catch: int | None) -> None:
        self.vfc.append((counter, preset, catch))

    def listens(self, index: int) -> bool:
        return index in self.by_input

    def poll(self, t: float | None = None) -> None:
        """Sample the preset and catch inputs of the very fast counters."""
        i = self.i_field
        for c, pre, cat in self.vfc:
            c.inputs(None if pre is None else i[pre], None if cat is None else i[cat], t)

    def feed(self, index: int, edges: int, direction: int | None, t: float, dt: float
             ) -> None:
        listeners = self.by_input.get(index)
        if not listeners:
            return
        if self.vfc:
            self.poll(t)
        for counter, dir_input in listeners:
            d = direction
            if d is None:
                d = 1 if dir_input is None or self.i_field[dir_input] else -1
            counter.pulses(edges, d, t, dt)


# ---- set-up (the catalog's hooks, run by softplc.assembly.blocks) --------------------------------
def setup_counters(ctx: Any, family: Any, entries: dict[str, Any]) -> None:
    """A counter family's configured blocks on the profile's inputs (an input used by two
    counters is an error), fed through one `CountingInputs` (`mem.counting`)."""
    hub = ctx.shared.setdefault("counting", CountingInputs(ctx.mem.i_field))
    for key, o in entries.items():
        ref = ctx.block_ref(key, family, f"counter (%{family.kind}0 ..)")
        ctx.mem.blocks[family.kind][ref.index] = family.block_class.configured(
            ctx, hub, ref, o, ctx.where(family.section, key))


def finish_counters(ctx: Any) -> None:
    """`mem.counting` for the sources; the preset / catch inputs sampled at each scan."""
    hub = ctx.shared.get("counting")
    if hub is None:
        return
    ctx.mem.counting = hub
    if hub.vfc:
        ctx.engine.before_scan.append(hub.poll)
