"""What every Twido function block shares: `Block`, `TimedBlock` and the scan's
`TimeSource`. The families are one module each: the basic ones in `softplc/blocks/`
(timers, counters, drums, registers, shift registers, step counters), the others beside
the runtime part they drive (`pulse.py`, `fastcount.py`, `pid.py`, `exch.py`), each named
by its entry of `softplc/twido/catalog.py`.

Each block exposes its fields as attributes named like the Twido fields (`.Q`, `.V`, `.P`
...), one method per input pin for the short form (`CU %C0` -> `cu`; a timer's one pin is
`run`), and `run(...)` taking all input pins at once for the `BLK ... END_BLK` form.
"""

from __future__ import annotations

from typing import Any

MAX_VALUE = 9999  # the timers' and counters' .P/.V range [manual]


class TimeSource:
    """Shared with the engine: the current scan's start time, and the timers in the middle
    of timing (so that the engine can update those the program did not execute)."""

    def __init__(self) -> None:
        self.now_us = 0
        self.running: set[Any] = set()  # timers (softplc/blocks/timer.py)
        # False when every timer block runs in every scan (no jump, subroutine, Grafcet
        # step or conditional end in the program): then nothing needs tracking
        self.track = True

    def update_running(self) -> None:
        """End of the scan: a timer keeps timing when its block is not executed (jumped
        over, in an uncalled subroutine or an inactive step): %TMi.V counts on and %TMi.Q
        changes at the preset [manual: TWD USE 10AE, timer "special cases", "effect of a
        program jump"]; those the program executed in this scan are up to date."""
        done = []
        now = self.now_us
        for t in self.running:
            if t._seen != now:
                t.run(t._in)
            if not (t._on if t._is_ton is False else t._in and t.V < t.P):  # t.timing
                done.append(t)
        for t in done:
            self.running.discard(t)


class Block:
    PINS: tuple[str, ...] = ()
    FIELDS: tuple[str, ...] = ()
    EDGE_PINS: dict[str, str] = {}  # rising-edge inputs -> attribute with their last value

    def __init_subclass__(cls, **kw: Any) -> None:
        """The short form (`CU %C0`, `R %R0`): one method per input pin (`cu`, `r`...) that
        runs the block with that input, holding the edge inputs at their last value (no
        edge) and the level inputs at 0. Generated, so each is one plain call to `run`.
        A class may still define a pin method itself (`run` serves a timer's IN)."""
        super().__init_subclass__(**kw)
        for pin in cls.PINS:
            name = pin.lower()
            if pin == "IN" or name in cls.__dict__:
                continue
            held = "".join(f", {p}=self.{a}" for p, a in cls.EDGE_PINS.items() if p != pin)
            ns: dict[str, Any] = {}
            exec(f"def {name}(self, v):\n    self.run({pin}=v{held})\n", ns)
            setattr(cls, name, ns[name])

    def state(self) -> dict[str, Any]:
        return {f: getattr(self, f) for f in self.FIELDS}

    def set_state(self, d: dict[str, Any]) -> None:
        for k, v in d.items():
            setattr(self, k, v)


class TimedBlock(Block):
    """A block with a start time `_t0` on `self.clock` (a TimeSource): its state holds the
    time elapsed since (`_elapsed_us`), valid whatever clock the state is restored under
    (a restart's starts again at 0). Timers, pulse outputs (runtime/pulse.py)."""

    clock: TimeSource

    def state(self) -> dict[str, Any]:
        st = super().state()
        st["_elapsed_us"] = self.clock.now_us - st.pop("_t0")
        return st

    def set_state(self, d: dict[str, Any]) -> None:
        d = dict(d)
        if "_elapsed_us" in d:
            d["_t0"] = self.clock.now_us - d.pop("_elapsed_us")
        super().set_state(d)
