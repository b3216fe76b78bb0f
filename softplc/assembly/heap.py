"""Give freed heap memory back to the operating system after a large transient peak.

CPython's `compile()` of a large generated program (10,000 rungs: 0.7 MB of source) takes
about 100 MiB of C heap for its syntax tree and code tables and frees it all, but glibc's
malloc keeps freed memory mapped: the process stays that much bigger (RSS) for its whole
life. `malloc_trim(0)` returns it (measured with tools/bench_compile.py:
docs/performance.md). Elsewhere than glibc, or when libc cannot be loaded, nothing happens.
"""

from __future__ import annotations

import ctypes
from functools import lru_cache
from typing import Any


@lru_cache(maxsize=1)
def _libc() -> Any:
    # the process's own symbols (dlopen(NULL)): libc is loaded already, and
    # ctypes.util.find_library would start a subprocess to look for it
    try:
        libc = ctypes.CDLL(None)
    except OSError:
        return None
    return libc if hasattr(libc, "malloc_trim") else None


def release_free_memory() -> bool:
    """Return the C heap's free memory to the OS; False where that is not possible."""
    libc = _libc()
    if libc is None:
        return False
    libc.malloc_trim(0)
    return True
