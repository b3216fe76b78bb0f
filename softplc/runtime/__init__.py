"""Run time: memory image, function blocks, clocks, the scan engine."""

# pulse outputs (issue 11 B): registers %PLS / %PWM in blocks.BLOCK_CLASSES on import
from . import pulse  # noqa: E402,F401
