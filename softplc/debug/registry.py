"""The debugger's command table and what its commands share: `@command` registers a
function `fn(session, arg) -> str` under a name and aliases (its docstring's first sentence
is its `help` line); `Session.execute` looks commands up here. The commands themselves are
grouped by family in `cmd_run.py` (execution), `cmd_breaks.py` (breakpoints, watches),
`cmd_data.py` (reading, writing, forcing, tracing) and `cmd_views.py` (blocks, status,
rungs, help). A new command: a function with `@command` in its family's module."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable

from softplc.debug.stepper import DebugError
from softplc.twido.semantics import COMPARE, COMPARE_PY

# the Twido operators and their Python spellings (== !=), as users also type them
CMP_OPS = {**COMPARE, **{COMPARE_PY[op]: fn for op, fn in COMPARE.items()}}
COND = re.compile(r"^\s*(\S+)\s*(==|=|<>|!=|<=|>=|<|>)\s*(\S+)\s*$")


def parse_value(text: str) -> int | float:
    """A number as the user types it: 12, -3, 16#FF, 0xFF, 2#1010, 1.5, true/false."""
    t = text.strip().lower().replace("_", "")
    if t in ("true", "on"):
        return 1
    if t in ("false", "off"):
        return 0
    try:
        if t.startswith("16#"):
            return int(t[3:], 16)
        if t.startswith("2#"):
            return int(t[2:], 2)
        if t.startswith(("0x", "-0x")):
            return int(t, 16)
        return int(t)
    except ValueError:
        pass
    try:
        v = float(t)
    except ValueError:
        raise DebugError(f"bad value {text!r}: a number (12, -3, 16#FF, 2#1010, 1.5)") from None
    if not math.isfinite(v):
        raise DebugError(f"bad value {text!r}")
    return v



@dataclasses.dataclass(frozen=True)
class Command:
    """One debugger command: the method that runs it, its help text, its other names and
    whether it takes a /FORMAT (print/x)."""

    name: str
    fn: Callable[..., str]
    doc: str
    aliases: tuple[str, ...] = ()
    formats: bool = False


# The command table: every command, filled by `@command` in the cmd_*.py modules.
COMMANDS: dict[str, Command] = {}


def command(name: str, *aliases: str, formats: bool = False
            ) -> Callable[[Callable[..., str]], Callable[..., str]]:
    """Register `fn(session, arg)` as the command `name` (and its aliases)."""
    def register(fn: Callable[..., str]) -> Callable[..., str]:
        COMMANDS[name] = Command(name, fn, (fn.__doc__ or "").strip(), aliases, formats)
        return fn
    return register



def first_sentence(doc: str) -> str:
    """The first sentence of a docstring, whole, on one line ("e.g.", "i.e.", an ellipsis
    and decimal points do not end it)."""
    text = " ".join(doc.split("\n\n")[0].split())
    m = re.search(r"(?<!\be\.g)(?<!\bi\.e)(?<!\.)\.(?=\s|$)", text)
    return text[: m.end()] if m else text
