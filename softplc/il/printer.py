"""AST -> Instruction List text, in TwidoSuite export layout.

`parse(format_program(p))` gives back `p` (positions aside): the round trip the property
tests check. Also used by the debugger and the ladder view to show one instruction.
"""

from __future__ import annotations

from collections.abc import Callable

from softplc.il import ast as A
from softplc.twido.address import Ref

# How an object is written: its address by default; the formatter passes one that keeps
# the symbols a line was written with.
RefText = Callable[[Ref], str]


def format_expr(e: A.Expr, top: bool = True, name: RefText = str) -> str:
    if isinstance(e, A.Num):
        if e.text:  # as written: #FFFF is a bit pattern (-1 in a word), 65535 does not fit
            return e.text
        if e.is_float:
            return repr(float(e.value))
        return str(e.value)
    if isinstance(e, A.Addr):
        return name(e.ref)
    if isinstance(e, A.Neg):
        return f"-{format_expr(e.operand, False, name)}"
    if isinstance(e, A.Call):
        return f"{e.func}( {', '.join(format_expr(a, True, name) for a in e.args)} )"
    if isinstance(e, A.BinOp):
        s = f"{format_expr(e.left, False, name)} {e.op} {format_expr(e.right, False, name)}"
        return s if top else f"( {s} )"
    raise TypeError(f"not an expression: {e!r}")


def format_operand(op: A.BoolOperand | None, name: RefText = str) -> str:
    if op is None:
        return ""
    if isinstance(op, A.Const):
        return str(op.value)
    if isinstance(op, A.Operand):
        return name(op.ref)
    if isinstance(op, A.BlockOutput):
        return op.name
    if isinstance(op, A.Compare):
        return f"[ {format_expr(op.left, True, name)} {op.op} {format_expr(op.right, True, name)} ]"
    raise TypeError(f"not an operand: {op!r}")


def format_statement(st: A.Statement, name: RefText = str) -> str:
    if isinstance(st, A.IncDec):
        return f"[ {st.op} {name(st.target)} ]"
    if isinstance(st, A.BlockCall):
        return f"[ {st.keyword} {st.number} ]"
    if isinstance(st, A.ExchCall):  # the ladder view's box text
        return f"EXCH{st.port} {name(st.table)}"
    return f"[ {name(st.target)} := {format_expr(st.expr, True, name)} ]"


def format_instruction(i: A.Instruction, name: RefText = str) -> str:
    """One instruction as TwidoSuite writes it: opcode padded to 6 columns."""
    def pad(op: str, arg: str = "") -> str:
        return f"{op:<6}{arg}".rstrip() if arg else op

    if isinstance(i, A.BoolInstr):
        return pad(i.op + i.modifier, format_operand(i.operand, name))
    if isinstance(i, A.ParenOpen):
        return pad(f"{i.op}({i.modifier}", format_operand(i.operand, name))
    if isinstance(i, A.ParenClose):
        return ")"
    if isinstance(i, A.Store):
        return pad(i.op, name(i.target))
    if isinstance(i, A.Negate):
        return "N"
    if isinstance(i, A.Stack):
        return i.op
    if isinstance(i, A.OpBlock) and isinstance(i.stmt, A.ExchCall):
        return pad(f"EXCH{i.stmt.port}", name(i.stmt.table))  # an instruction of its own
    if isinstance(i, A.OpBlock):
        return format_statement(i.stmt, name)
    if isinstance(i, A.Jump):
        return pad(i.op, f"%L{i.label}")
    if isinstance(i, A.SRCall):
        return f"SR{i.number}"
    if isinstance(i, (A.Return, A.End)):
        return i.op
    if isinstance(i, A.Nop):
        return "NOP"
    if isinstance(i, A.Blk):
        return pad("BLK", name(i.block))
    if isinstance(i, A.OutBlk):
        return "OUT_BLK"
    if isinstance(i, A.EndBlk):
        return "END_BLK"
    if isinstance(i, A.Pin):
        return pad(i.name, name(i.block) if i.block else "")
    if isinstance(i, A.Grafcet):
        if i.op == "POST":
            return "=*= POST"
        return f"{i.op} {i.step}" if i.step is not None else i.op
    raise TypeError(f"not an instruction: {i!r}")


def format_program(p: A.Program) -> str:
    out: list[str] = []
    section: int | None = None
    sr: int | None = None
    for r in p.rungs:
        if r.subroutine is not None and r.subroutine != sr:
            sr = r.subroutine
            out.append(f"SR{sr}:")
        elif r.subroutine is None and r.section is not None and r.section != section:
            section = r.section
            out.append(f"SECTION     {section}")
            if section in p.section_titles:
                out.append(f"(*SECTTITLE:{p.section_titles[section]}*)")
        if r.title:
            out.append(f"(*{r.title}*)")
        if r.label is not None:
            out.append(f"%L{r.label}:")
        out.extend(format_instruction(i) for i in r.instructions)
    return "\n".join(out) + "\n"
