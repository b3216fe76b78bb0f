"""G-code for the drawing table: reader, preview, streaming host client, deviation metric.

    from softplc.gcode import parse_file, GCodeConfig, DrawClient, max_deviation
    prog = parse_file("square.gcode", GCodeConfig(plane="XZ"))
    steps = prog.steps()
    with DrawClient("127.0.0.1", 5020) as client:
        client.stream(steps)
    print(max_deviation(steps, "trace.csv", prog.config.steps_per_unit))
"""

from .deviation import Deviation, TraceError, load_trace, max_deviation
from .host import DrawClient, HostError, StreamResult, make_frame
from .parser import (
    GCodeConfig,
    GCodeError,
    Program,
    Segment,
    StepSegment,
    parse_file,
    parse_gcode,
    to_steps,
)
from .preview import preview

__all__ = [
    "Deviation",
    "DrawClient",
    "GCodeConfig",
    "GCodeError",
    "HostError",
    "Program",
    "Segment",
    "StepSegment",
    "StreamResult",
    "TraceError",
    "load_trace",
    "make_frame",
    "max_deviation",
    "parse_file",
    "parse_gcode",
    "preview",
    "to_steps",
]
