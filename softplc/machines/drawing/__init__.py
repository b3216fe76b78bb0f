"""The drawing table of seed 003: its G-code host client, the pen and the trace recorder
(its devices), the deviation of a drawing from its path, and `softplc draw`."""

from softplc.machines.lazy import lazy_exports

# name -> the submodule that defines it, imported on first use (machines/lazy.py)
_EXPORTS = {
    "Deviation": "deviation",
    "DrawClient": "host",
    "HostError": "host",
    "StreamResult": "host",
    "TraceError": "deviation",
    "load_trace": "deviation",
    "make_frame": "host",
    "max_deviation": "deviation",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
