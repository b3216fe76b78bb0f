"""The live ladder of the web monitor: the one place the web package uses the ladder
renderer (`softplc.ladder`), so that a change of that module's layout touches only
this file.

The daemon runs the fast build (no accumulator log), so power flow comes from the
contacts' current values, as the renderer does without a log. The values are those of one
scan: `refs` lists what a rung reads (from the rung's structure, `ladder.reads`), the scan
thread reads them, `capture` and `render` draw them here.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from softplc import ladder
from softplc.il import ast as A
from softplc.twido.address import Ref


def refs(rung: A.Rung) -> list[Ref]:
    """The objects a rung's live view reads."""
    return ladder.reads(rung)


def capture(wanted: list[Ref], values: list[Any]) -> dict[Ref, Any]:
    """One scan's values of `wanted` (read in the scan thread as a list, a function block
    as a dict of its fields) in the form `render` draws them."""
    return {ref: SimpleNamespace(**v) if isinstance(v, dict) else v
            for ref, v in zip(wanted, values, strict=True) if v is not None}


def render(rung: A.Rung, values: dict[Ref, Any], forced: set[str]) -> str:
    """The rung as SVG with power flow and values from `capture`."""
    def read(ref: Ref) -> Any:
        return values[ref]

    return ladder.render_rung_svg(rung, ladder.Live(read, None, forced))
