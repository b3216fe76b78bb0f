"""G-code, as the drawing and cutting tables read it: the reader (the preview is
`softplc.machines.gcode.preview.preview`).

    from softplc.machines.gcode import parse_file, GCodeConfig
    from softplc.machines.drawing import DrawClient, max_deviation
    prog = parse_file("square.gcode", GCodeConfig(plane="XZ"))
    steps = prog.steps()
    with DrawClient("127.0.0.1", 5020) as client:
        client.stream(steps)
    print(max_deviation(steps, "trace.csv", prog.config.steps_per_unit))
"""

from softplc.machines.lazy import lazy_exports

# name -> the submodule that defines it, imported on first use (machines/lazy.py)
_EXPORTS = {
    "GCodeConfig": "parser",
    "GCodeError": "parser",
    "Program": "parser",
    "Segment": "parser",
    "StepSegment": "parser",
    "parse_file": "parser",
    "parse_gcode": "parser",
    "to_steps": "parser",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
