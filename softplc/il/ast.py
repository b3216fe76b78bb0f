"""Typed AST of an Instruction List program.

Every node keeps its source position; equality ignores positions so that a program and
its printed-and-reparsed copy compare equal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from softplc.twido.address import Ref


@dataclass(frozen=True, slots=True)
class Pos:
    line: int
    column: int
    end_line: int = 0
    end_column: int = 0


NOPOS = Pos(0, 0)


def _pos() -> Pos:
    return field(default=NOPOS, compare=False, repr=False)


# ---- expressions (inside [ ] blocks) ------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Expr:
    pass


@dataclass(frozen=True, slots=True)
class Num(Expr):
    value: int | float
    text: str = field(default="", compare=False)  # as written: 1.0E3, #7FFF
    pos: Pos = _pos()

    @property
    def is_float(self) -> bool:
        return isinstance(self.value, float)


@dataclass(frozen=True, slots=True)
class Addr(Expr):
    ref: Ref
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class BinOp(Expr):
    op: str  # + - * / REM AND OR XOR
    left: Expr
    right: Expr
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Neg(Expr):
    operand: Expr
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Call(Expr):
    func: str  # canonical upper-case name (aliases resolved)
    args: tuple[Expr, ...]
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Compare:
    op: str  # > >= < <= = <>
    left: Expr
    right: Expr
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Const:
    """Boolean operand 0 / 1."""

    value: int
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class BlockOutput:
    """`Q`, `D`, `E`, `F` after OUT_BLK: an output of the enclosing block."""

    name: str
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Operand:
    """A reference used as a boolean operand."""

    ref: Ref
    pos: Pos = _pos()


BoolOperand = Operand | Const | Compare | BlockOutput


# ---- statements in operation blocks -------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Assign:
    target: Ref
    expr: Expr
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class IncDec:
    op: str  # INC | DEC
    target: Ref
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class BlockCall:
    """`[ KEYWORD n ]`: run block n of the family whose catalog `instruction` is KEYWORD
    (`[ PID 0 ]`: PID function 0, configured in [pid]) [manual]."""

    keyword: str
    number: int
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class ExchCall:
    """`EXCHi %MWj:n`: start an exchange on port i with the table %MWj:n [manual]; an
    instruction of its own in the text, held as an operation-block statement (it runs
    when the accumulator is 1, like one)."""

    port: int
    table: Ref
    pos: Pos = _pos()


Statement = Assign | IncDec | BlockCall | ExchCall


# ---- instructions -------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Instruction:
    pass


@dataclass(frozen=True, slots=True)
class BoolInstr(Instruction):
    """LD / AND / OR / XOR with modifier '' | 'N' | 'R' | 'F'."""

    op: str
    modifier: str
    operand: BoolOperand
    pos: Pos = _pos()

    @property
    def is_load(self) -> bool:
        return self.op == "LD"


@dataclass(frozen=True, slots=True)
class ParenOpen(Instruction):
    op: str  # AND | OR | XOR
    modifier: str  # '' | N | R | F
    operand: BoolOperand | None
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class ParenClose(Instruction):
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Store(Instruction):
    op: str  # ST STN S R
    target: Ref
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Negate(Instruction):
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Stack(Instruction):
    op: str  # MPS MRD MPP
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class OpBlock(Instruction):
    stmt: Statement
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Jump(Instruction):
    op: str  # JMP JMPC JMPCN
    label: int
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class SRCall(Instruction):
    number: int
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Return(Instruction):
    op: str  # RET RETC RETCN
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class End(Instruction):
    op: str  # END ENDC ENDCN
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Nop(Instruction):
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Blk(Instruction):
    block: Ref
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class OutBlk(Instruction):
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class EndBlk(Instruction):
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Pin(Instruction):
    """A block input: `IN`, `R`, `S`, `CU`, `CD`, `U`, `I`, `O`.

    Inside BLK ... OUT_BLK `block` is None; the short form `IN %TM0` names the block."""

    name: str
    block: Ref | None
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Label(Instruction):
    number: int
    pos: Pos = _pos()


@dataclass(frozen=True, slots=True)
class Grafcet(Instruction):
    op: str  # "=*=" initial step, "-*-" step, "POST", "#" jump, "#D" deactivate
    step: int | None
    pos: Pos = _pos()


# ---- program structure --------------------------------------------------------------------
@dataclass(slots=True)
class Rung:
    """A rung: from a load (or BLK) after the previous rung's outputs to its last output."""

    index: int  # global rung number, in source order
    instructions: list[Instruction]
    title: str = ""
    section: int | None = None
    subroutine: int | None = None  # SR number if the rung is in a subroutine
    label: int | None = None  # %Li: at the start of the rung
    first_line: int = 0
    last_line: int = 0
    label_line: int = 0  # line of the `%Li:` that starts the rung

    @property
    def name(self) -> str:
        return f"rung {self.index}" + (f" ({self.title})" if self.title else "")


@dataclass(slots=True)
class Program:
    file: str
    source: str
    rungs: list[Rung]  # all rungs, main program first, then subroutines
    section_titles: dict[int, str] = field(default_factory=dict)

    @property
    def main(self) -> list[Rung]:
        return [r for r in self.rungs if r.subroutine is None]

    def subroutine(self, n: int) -> list[Rung]:
        return [r for r in self.rungs if r.subroutine == n]

    @property
    def subroutines(self) -> list[int]:
        return sorted({r.subroutine for r in self.rungs if r.subroutine is not None})

    def rung(self, key: int | str) -> Rung:
        """A rung by number or by (case-insensitive) title."""
        if isinstance(key, int) or (isinstance(key, str) and key.strip().isdigit()):
            return self.rungs[int(key)]
        k = key.strip().lower()
        for r in self.rungs:
            if r.title.lower() == k:
                return r
        for r in self.rungs:
            if k in r.title.lower():
                return r
        raise KeyError(key)
