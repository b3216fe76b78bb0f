"""One cache of the code objects of generated Python source (a program's rungs, a scan, a
servo loop).

The same text is compiled again and again: a scan is regenerated at every force, state or
online change and is often the same text as before, an online change back to a program
compiles its rungs again, the verifier builds an engine per counterexample, and a test
suite builds the same shipped program hundreds of times. CPython's `compile()` is the
larger part of that work (about 1.5 ms for a scan, more for a long rung text), and a code
object is immutable: executed in another namespace it makes new functions, so one per text
serves every engine.
"""

from __future__ import annotations

import functools
from types import CodeType

# Code objects kept (least recently used first out): a daemon holds a few (its scan
# variants and its program's defs); a test suite's hundreds of programs mostly hit.
CACHE_ENTRIES = 256
# Longer texts (a generated program of thousands of rungs) are compiled each time: the
# cache must not hold megabytes of source, and such a program is rarely compiled twice.
CACHE_MAX_CHARS = 64 * 1024


@functools.lru_cache(maxsize=CACHE_ENTRIES)
def _compiled(text: str, filename: str) -> CodeType:
    return compile(text, filename, "exec")


def compile_code(text: str, filename: str) -> CodeType:
    """`compile(text, filename, "exec")`, from the cache when the same text and file name
    were compiled before."""
    if len(text) > CACHE_MAX_CHARS:
        return compile(text, filename, "exec")
    return _compiled(text, filename)
