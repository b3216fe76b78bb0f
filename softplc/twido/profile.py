"""Controller profiles: how many of each object a Twido model has.

This table is the one place that knows object counts (the function blocks' counts come
from their catalog entries, `softplc/twido/catalog.py`). A larger controller is one more entry.
Counts are the documented TWDLCAE40DRF figures (TWD USE 10AE) [manual].
"""

from __future__ import annotations

from dataclasses import dataclass, field

from softplc.twido import catalog


@dataclass(frozen=True)
class FastCounterWiring:
    """%FCi: its counting input (channel of %I0.x) and the input's highest frequency."""

    input: int
    max_hz: float


@dataclass(frozen=True)
class VeryFastCounterWiring:
    """%VFCi: pulse / phase A input, direction / phase B input, preset and catch inputs
    (channels of %I0.x), the two reflex outputs (channels of %Q0.x), highest frequency."""

    pulse: int
    direction: int
    preset: int
    catch: int
    reflex: tuple[int, int]
    max_hz: float


@dataclass(frozen=True)
class Profile:
    name: str
    inputs_base: int  # %I0.0 .. %I0.(n-1)
    outputs_base: int  # %Q0.0 .. %Q0.(n-1)
    expansion_slots: int  # modules 1..n
    channels_per_module: int  # widest expansion module (TM2 DDI32/DDO32)
    counts: dict[str, int] = field(default_factory=dict)
    # The base's analog inputs %IW0.0, %IW0.1...: (signal type, full-scale count) each.
    analog_base: tuple[tuple[str, int], ...] = ()
    # %Q0.x driven by %PLSi / %PWMi (index i): the base's transistor outputs
    pulse_outputs: tuple[int, ...] = ()
    # fast counters (runtime/fastcount.py): the wiring of %FCi and %VFCi on the base
    fast_counters: tuple[FastCounterWiring, ...] = ()
    very_fast_counters: tuple[VeryFastCounterWiring, ...] = ()

    def count(self, kind: str) -> int:
        return self.counts[kind]


TWDLCAE40DRF = Profile(
    name="TWDLCAE40DRF",
    inputs_base=24,
    outputs_base=16,
    expansion_slots=7,
    channels_per_module=32,
    counts={
        "M": 256,
        "MW": 3000,
        "KW": 256,
        "S": 128,
        "SW": 128,
        "L": 64,
        "SR": 64,
        "X": 96,  # Grafcet steps %X0..%X95
        "FIFO_DEPTH": 16,  # %Ri register depth
        "DRUM_STEPS": 8,
        "STACK": 8,  # MPS depth [m221]
        "PAREN": 8,  # parenthesis nesting [manual]
        # the Ethernet port's remote devices 1..16 (runtime/exch.py) [manual, from memory]
        "EXCH_REMOTES": 16,
        # the function blocks: their catalog entries (%TM0..%TM127, PID 0..13...)
        **{f.kind: f.count for f in catalog.FAMILIES.values()},
    },
    # two analog potentiometers and one 0-10 V input, 10 bits [manual, from memory: the
    # hardware guide's figures were not found in the search corpora; check the counts]
    analog_base=(("pot", 1023), ("pot", 1023), ("0-10V", 1023)),
    # 14 relay outputs and 2 transistor outputs %Q0.0, %Q0.1: those carry PLS / PWM
    # [manual: hardware guide quoted in seed thesis 003]
    pulse_outputs=(0, 1),
    # fast counters [manual, from memory of TWD USE 10AE / the hardware guide: not found in
    # the search corpora; check]: %FC0..3 on %I0.2..%I0.5 at 5 kHz; %VFC0 pulses (phase A)
    # %I0.1, direction (phase B) %I0.0, preset %I0.2, catch %I0.3, reflex %Q0.2/%Q0.3;
    # %VFC1 %I0.7, %I0.6, %I0.5, %I0.4, reflex %Q0.4/%Q0.5; 20 kHz
    fast_counters=tuple(FastCounterWiring(i, 5_000.0) for i in (2, 3, 4, 5)),
    very_fast_counters=(VeryFastCounterWiring(1, 0, 2, 3, (2, 3), 20_000.0),
                        VeryFastCounterWiring(7, 6, 5, 4, (4, 5), 20_000.0)),
)

# Known expansion modules: digital inputs / outputs per module.
MODULES: dict[str, tuple[int, int]] = {
    "TM2DDI8DT": (8, 0),
    "TM2DDI16DT": (16, 0),
    "TM2DDI32DK": (32, 0),
    "TM2DDO8TT": (0, 8),
    "TM2DDO8UT": (0, 8),
    "TM2DRA8RT": (0, 8),
    "TM2DDO16TK": (0, 16),
    "TM2DDO32TK": (0, 32),
    "TM2DMM8DRT": (4, 4),
    "TM2DMM24DRF": (16, 8),
}



@dataclass(frozen=True)
class AnalogModule:
    """An analog expansion module: %IWm.0.. inputs, %QWm.0.. outputs, the signal types
    TwidoSuite offers for them, 12-bit resolution (0..4095 in the normal range)."""

    inputs: int
    outputs: int
    input_types: tuple[str, ...]
    output_types: tuple[str, ...]
    full_scale: int = 4095


_V_MA = ("0-10V", "4-20mA")
# [manual, from memory of the Twido hardware guide; not found in the search corpora]
ANALOG_MODULES: dict[str, AnalogModule] = {
    "TWDAMI2HT": AnalogModule(2, 0, _V_MA, ()),
    "TWDAMO1HT": AnalogModule(0, 1, (), _V_MA),
    "TWDAMM3HT": AnalogModule(2, 1, _V_MA, _V_MA),
    "TWDALM3LT": AnalogModule(2, 1, ("PT100", "J", "K", "T"), _V_MA),
    "TWDAVO2HT": AnalogModule(0, 2, (), ("+-10V",)),
}

PROFILES = {TWDLCAE40DRF.name: TWDLCAE40DRF}
DEFAULT_PROFILE = TWDLCAE40DRF
