"""softplc vs awlsim (an S7 STL interpreter in Python, PyPI `awlsim`).

The same boolean program (tools/gen_programs.boolean_program) and a word program are
translated from IL to STL (peers/programs.py) and run as OB1. Reported: time per scan /
cycle, instructions per second on each side counting each side's own instructions (an IL
`AND( %M1` is one instruction, in STL `U(` + `U M 0.1` are two), and the ratio of the time
per scan of the same logic, the fair figure. Timed runs of both sides alternate.
"""

from __future__ import annotations

from typing import Any

from gen_programs import boolean_program

from softplc.plc import PLC

from .common import best_interleaved, loop, version_of
from .programs import to_stl, word_program, word_to_stl


def _imports() -> tuple[Any, Any, Any]:
    # awlsim's modules resolve names through each other's star imports: this order (the
    # one of its own awlsim-test) matters, awlcompiler first fails with a NameError.
    import awlsim.common as common
    import awlsim.core as core
    import awlsim.awlcompiler as compiler  # isort: skip

    return common.AwlSource, core.AwlSim, compiler.AwlParser


def available() -> str | None:
    try:
        _imports()
    except Exception as e:  # any import failure makes the peer unavailable
        return f"{type(e).__name__}: {e}"
    return None


def load_stl(source: str) -> Any:
    """An awlsim core with `source` loaded and started."""
    AwlSource, AwlSim, AwlParser = _imports()
    p = AwlParser()
    p.parseSource(AwlSource(name="bench", sourceBytes=source.encode()))
    sim = AwlSim()
    sim.reset()
    sim.load(p.getParseTree())
    sim.build()
    sim.startup()
    return sim


def run(scans: int = 500, repeat: int = 3, warmup: int = 50) -> dict[str, Any]:
    reason = available()
    if reason:
        return {"unavailable": reason}
    out: dict[str, Any] = {"version": version_of("awlsim"), "scans": scans, "repeat": repeat}
    cases = {"boolean": ("boolean program (gen_programs, 1000 IL instructions)",
                         boolean_program(1000), to_stl),
             "words": ("word program (250 x [ %MWa := %MWb + %MWc ])", word_program(250),
                       word_to_stl)}
    for key, (label, il, translate) in cases.items():
        stl, n_stl = translate(il)
        plc = PLC.from_source(il)
        n_il = plc.program.instruction_count
        try:
            sim = load_stl(stl)
            t = best_interleaved({"softplc": plc.scan, "awlsim": loop(sim.runCycle)}, scans,
                                 repeat, warmup)
        except Exception as e:  # awlsim raises its own error classes; report, don't crash
            out[key] = {"label": label, "error": f"{type(e).__name__}: {e}"}
            continue
        t_soft, t_awl = t["softplc"], t["awlsim"]
        out[key] = {"label": label, "il_instructions": n_il, "stl_instructions": n_stl,
                    "softplc_us": t_soft * 1e6, "awlsim_us": t_awl * 1e6,
                    "softplc_instr_per_s": n_il / t_soft, "awlsim_instr_per_s": n_stl / t_awl,
                    "ratio": t_awl / t_soft}
    return out
