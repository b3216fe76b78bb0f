"""How many examples the fuzzers and the slow property tests run: a quarter of their full
count in the suite (it must stay under 5 minutes on 2 cores), the full count with
`SOFTPLC_FUZZ=1` (`make fuzz`), any other factor with `SOFTPLC_FUZZ=<factor>`. The tests
are not derandomised (except where said), so each suite run draws new examples."""

from __future__ import annotations

import os

SUITE_FACTOR = 0.25


def factor() -> float:
    text = os.environ.get("SOFTPLC_FUZZ", "")
    try:
        value = float(text) if text else SUITE_FACTOR
    except ValueError:
        raise ValueError(f"SOFTPLC_FUZZ={text!r}: expected a factor such as 1 or 0.25") from None
    if value <= 0:
        raise ValueError(f"SOFTPLC_FUZZ={text!r}: expected a factor > 0")
    return value


def examples(full: int) -> int:
    """The example count for a test whose full count is `full` (at least 10)."""
    return max(10, round(full * factor()))
