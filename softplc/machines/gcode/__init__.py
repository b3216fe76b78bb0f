"""G-code, as the drawing and cutting tables read it: the reader and the preview.

    from softplc.machines.gcode import parse_file, GCodeConfig
    from softplc.machines.drawing import DrawClient, max_deviation
    prog = parse_file("square.gcode", GCodeConfig(plane="XZ"))
    steps = prog.steps()
    with DrawClient("127.0.0.1", 5020) as client:
        client.stream(steps)
    print(max_deviation(steps, "trace.csv", prog.config.steps_per_unit))
"""

from softplc.machines.gcode.parser import (
    GCodeConfig,
    GCodeError,
    Program,
    Segment,
    StepSegment,
    parse_file,
    parse_gcode,
    to_steps,
)
from softplc.machines.gcode.preview import preview

__all__ = [
    "GCodeConfig",
    "GCodeError",
    "Program",
    "Segment",
    "StepSegment",
    "parse_file",
    "parse_gcode",
    "preview",
    "to_steps",
]
