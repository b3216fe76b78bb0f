"""Run time: memory image, function blocks, clocks, the scan engine."""

from . import blocks  # noqa: F401,E402  (first: runtime/fastcount.py imports blocks.Block)
