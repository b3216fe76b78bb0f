"""The contract between compiled code and the runtime.

Code generation (`softplc/compiler/`) writes Python that refers to a fixed set of names;
the runtime (`softplc/plc.py`, `softplc/runtime/engine.py`, the debugger) binds those names
to the memory image, the instruction helpers and the per-program state. Both sides take the
names from here, so neither hard-codes the other's strings, and the runtime never imports
the compiler:

    compiler ──► program.py ◄── runtime / plc / debug

- `Names`: the one bindings table (memory buffers, helpers, program state, control).
- `ProgramState`: what a program keeps between scans besides the memory image: edge memory
  of `LDR`/`LDF`..., the Grafcet transitions of the scan, the initial steps.
- `CompiledProgram`: the generated source, its entry point and namespace, its state.
- `bind()`: the namespace a compiled program runs in.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from softplc.il import ast as A
from softplc.twido import catalog
from softplc.twido.semantics import Ops


class Watchdog(Exception):
    """Raised by compiled code when a scan overruns the watchdog inside a loop."""


class Names:
    """The names compiled code may use (besides its own locals and functions)."""

    BIT = {"I": "_I", "Q": "_Q", "M": "_M", "S": "_S", "X": "_X"}  # bit lists
    # signed 16-bit views (%IW/%QW: analog I/O words; %INW/%QNW: Remote Link words)
    WORD = {"MW": "_MW", "KW": "_KW", "SW": "_SW", "IW": "_IW", "QW": "_QW",
            "INW": "_INW", "QNW": "_QNW"}
    UWORD = {"MW": "_UMW", "KW": "_UKW", "SW": "_USW", "IW": "_UIW", "QW": "_UQW",
             "INW": "_UINW", "QNW": "_UQNW"}
    # 32-bit views at even / odd word offsets (index i -> view[i & 1][i >> 1])
    PAIR = {"MD": ("_MDE", "_MDO"), "KD": ("_KDE", "_KDO"),
            "MF": ("_MFE", "_MFO"), "KF": ("_KFE", "_KFO")}
    FAMILY = {"MW": "_MWF", "MD": "_MWF", "MF": "_MWF", "KW": "_KWF", "KD": "_KWF",
              "KF": "_KWF", "SW": "_SWF"}  # WordFamily objects (indexed 32-bit access)
    MEM = "_mem"  # the MemoryImage (tables, bit strings)
    EDGE = "_EDGE"  # edge memory of LDR/LDF/ANDR...: ProgramState.edges
    ACTIVATE = "_GA"  # Grafcet steps to activate at the end of sequential processing
    DEACTIVATE = "_GD"  # ... and to deactivate
    GRAFCET_PRE = "_gpre"  # end of preprocessing: act on %S21-%S23
    GRAFCET_POST = "_gpost"  # apply them (unless %S23 froze the chart)
    STEPS_AT_START = "_XS"  # local: the step bits as the scan's sequential part began
    WATCHDOG = "_wd"  # () -> bool: the scan overran the watchdog
    WATCHDOG_EXC = "_Watchdog"
    LOG = "_LOG"  # debug build: accumulator after each instruction
    HELPERS = frozenset("_" + n for n in Ops.helper_names())  # semantics.Ops methods
    MAIN = "_main"

    @staticmethod
    def helper(name: str) -> str:
        """The bound name of the `semantics.Ops` helper `name` (e.g. "add16")."""
        bound = "_" + name
        if bound not in Names.HELPERS:
            raise KeyError(f"no instruction helper {name!r} in semantics.Ops")
        return bound

    @staticmethod
    def block(kind: str, index: int) -> str:
        return f"_{kind}{index}"

    @staticmethod
    def subroutine(n: int) -> str:
        return f"_sr{n}"

    @classmethod
    def fixed(cls) -> frozenset[str]:
        """Every name of the table except blocks and subroutines (patterns)."""
        out = set(cls.BIT.values()) | set(cls.WORD.values()) | set(cls.UWORD.values())
        out |= {n for pair in cls.PAIR.values() for n in pair} | set(cls.FAMILY.values())
        out |= {cls.MEM, cls.EDGE, cls.ACTIVATE, cls.DEACTIVATE, cls.GRAFCET_PRE, cls.GRAFCET_POST,
                cls.WATCHDOG, cls.WATCHDOG_EXC, cls.LOG, cls.MAIN}
        return frozenset(out | cls.HELPERS)

    _BLOCK = re.compile(rf"_({'|'.join(catalog.FAMILIES)})\d+$")  # every block family
    _SR = re.compile(r"_sr\d+$")

    @classmethod
    def is_bound(cls, name: str) -> bool:
        """Whether `name` is one the runtime binds (or a program function)."""
        return name in _FIXED or bool(cls._BLOCK.match(name) or cls._SR.match(name))


_FIXED = Names.fixed()


@dataclass
class ProgramState:
    """What a program keeps between scans outside the memory image."""

    edges: list[int] = field(default_factory=list)  # previous operand value per edge instr
    activate: list[int] = field(default_factory=list)  # Grafcet: steps to set at POST
    deactivate: list[int] = field(default_factory=list)  # ... and to reset
    initial_steps: tuple[int, ...] = ()
    # the runtime's Grafcet (`runtime.grafcet.Grafcet`: %S21-%S23, applying the transitions);
    # when given, `activate`/`deactivate` are its lists
    grafcet: Any = None

    def __post_init__(self) -> None:
        if self.grafcet is not None:
            self.activate, self.deactivate = self.grafcet.ga, self.grafcet.gd

    def size_edges(self, n: int) -> None:
        """At least `n` edge cells (in place: compiled code holds the list)."""
        if len(self.edges) < n:
            self.edges.extend([0] * (n - len(self.edges)))

    def cold_start(self, x: list[bool]) -> None:
        """Edges forgotten, no pending transition, the initial steps active."""
        self.edges[:] = [0] * len(self.edges)
        self.clear_transitions()
        for step in self.initial_steps:
            x[step] = True

    def clear_transitions(self) -> None:
        """Forget the transitions of an abandoned scan (the debugger's stepping back)."""
        self.activate.clear()
        self.deactivate.clear()
        if self.grafcet is not None:
            self.grafcet.frozen = 0

    def snapshot(self) -> dict[str, Any]:
        return {"edges": list(self.edges), "activate": list(self.activate),
                "deactivate": list(self.deactivate)}

    def restore(self, snap: dict[str, Any]) -> None:
        self.edges[:] = snap["edges"]
        self.activate[:] = snap["activate"]
        self.deactivate[:] = snap["deactivate"]


@dataclass
class CompiledProgram:
    program: A.Program
    source: str
    main: Callable[[], Any]
    namespace: dict[str, Any]
    state: ProgramState
    debug: bool = False
    log: list[list[Any]] = field(default_factory=list)  # debug: accumulator per instruction
    instruction_count: int = 0

    @property
    def rungs(self) -> list[A.Rung]:
        return self.program.rungs


def bind(mem: Any, ops: Ops, state: ProgramState, watchdog: Callable[[], bool],
         blocks: dict[str, dict[int, Any]]) -> dict[str, Any]:
    """The namespace compiled code runs in: every name of `Names`, bound."""
    N = Names
    env: dict[str, Any] = {N.MEM: mem, N.EDGE: state.edges, N.ACTIVATE: state.activate,
                           N.DEACTIVATE: state.deactivate, N.WATCHDOG: watchdog,
                           N.WATCHDOG_EXC: Watchdog}
    for kind, name in N.BIT.items():
        env[name] = mem.bits(kind)
    for kind, name in N.WORD.items():
        env[name] = mem.words(kind).w
        env[N.UWORD[kind]] = mem.words(kind).uw
    for kind, (even, odd) in N.PAIR.items():
        views = mem.words(kind).f if kind.endswith("F") else mem.words(kind).d
        env[even], env[odd] = views
    for kind, name in N.FAMILY.items():
        env[name] = mem.words(kind)
    for name, f in ops.table().items():
        env["_" + name] = f
    for kind, by_index in blocks.items():
        for i, b in by_index.items():
            env[N.block(kind, i)] = b
    env[N.GRAFCET_PRE], env[N.GRAFCET_POST] = state.grafcet.pre, state.grafcet.post
    return env
