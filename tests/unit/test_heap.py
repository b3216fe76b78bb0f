"""softplc.assembly.heap: freed C heap goes back to the OS after a large compile (issue 26)."""

from __future__ import annotations

import gc
import sys
from pathlib import Path

import pytest

from softplc.assembly.heap import release_free_memory


def _rss_mib() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc and /proc")
def test_compile_peak_is_given_back() -> None:
    # one large function, like the compiler's: compile() takes tens of MiB and frees them
    body = "\n".join(f"    m[{i % 500}] = m[{(i * 7) % 500}] and not m[{(i * 13) % 500}]"
                     for i in range(20_000))
    gc.collect()
    # the free memory earlier tests left in this worker's heap first: compile()'s peak
    # would be served from it (the RSS growing 14 MiB, not 30, after another order of tests)
    assert release_free_memory()
    start = _rss_mib()
    code = compile(f"def main(m):\n{body}\n", "<test>", "exec")  # kept, as the PLC does
    gc.collect()
    kept = _rss_mib()  # the code object is a few MiB; the rest is compile()'s freed peak
    assert kept > start + 30
    assert release_free_memory()
    assert _rss_mib() < kept - 30  # given back
    assert release_free_memory()  # nothing left: still fine
    assert code.co_consts  # alive until here
