"""The drawing table of seed 003: its G-code host client, the pen and the trace recorder
(its devices), the deviation of a drawing from its path, and `softplc draw`."""

from softplc.machines.drawing.deviation import Deviation, TraceError, load_trace, max_deviation
from softplc.machines.drawing.host import DrawClient, HostError, StreamResult, make_frame

__all__ = [
    "Deviation",
    "DrawClient",
    "HostError",
    "StreamResult",
    "TraceError",
    "load_trace",
    "make_frame",
    "max_deviation",
]
