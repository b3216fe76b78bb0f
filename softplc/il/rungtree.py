"""The structure of one rung, built once: the IL stack machine without values.

A rung's instructions drive an accumulator, a stack of open parentheses, the MPS stack and
the open BLK ... END_BLK block. This module runs that machine once, on structure only, and
records for every instruction (a `Step`) what it is connected to: the parenthesis a `)`
closes, the MPS an MRD/MPP reads, the block it sits in and on which side of OUT_BLK,
whether the accumulator holds a value before it and whether a later instruction reads the
accumulator it leaves. The rung-structure checks live here too, with their `errors.Code`.

Consumers keep only their own values, indexed by instruction number (`Step.k`):
code generation (`compiler/codegen.py`: Python expressions) and the ladder view
(`ladder/tree.py`: series/parallel drawings), so neither parses the stack machine.
A new instruction kind that reads the accumulator is added to `READS_ACC`; one that
changes the structure (a new kind of bracket or block) to `build`; then each consumer
handles it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from softplc.errors import Code
from softplc.il import ast as A
from softplc.twido import catalog
from softplc.twido.address import Ref


@dataclass(frozen=True)
class Problem:
    """A structure error; the compiler turns it into a `Diagnostic` (with the source line)."""

    message: str
    pos: A.Pos | None
    text: str
    expected: str
    code: Code


@dataclass
class Step:
    """One instruction in its place in the rung."""

    k: int  # index in the rung
    instr: A.Instruction
    block: Ref | None = None  # the open BLK (for BLK: the one it opens; END_BLK: closes)
    block_k: int | None = None  # the BLK instruction's index
    phase: str = ""  # before this instruction: "in" (BLK ... OUT_BLK), "out" (after OUT_BLK)
    has_acc: bool = False  # the accumulator holds a value before this instruction
    opener: int | None = None  # `)`: its `(`; MRD / MPP: the MPS it reads (None: none)
    used_later: bool = False  # a later instruction reads the accumulator left by this one
    ok: bool = True  # False: a structure error leaves the instruction out (no effect)

    @property
    def pos(self) -> A.Pos | None:
        return getattr(self.instr, "pos", None)


# Instructions that neither read nor replace the accumulator a later one sees (the markers
# of a block and of Grafcet steps, NOP): `used_later` looks through them.
_TRANSPARENT = (A.Blk, A.OutBlk, A.EndBlk, A.Nop)
NO_LIMIT = 1 << 30
_BLK_KINDS = [f"%{f.kind}" for f in catalog.FAMILIES.values() if f.in_blk_hint]
_BLK_HINT = f"{', '.join(_BLK_KINDS[:-1])} or {_BLK_KINDS[-1]}"  # what BLK takes, mostly
# Instructions that use the accumulator as their condition or input, so need a load before
# them (a new output-like instruction is added here). Jumps, END/RET and Grafcet
# instructions are not: whether they need one depends on their variant and function.
READS_ACC = (A.Negate, A.Store, A.OpBlock, A.SRCall, A.Pin)


def describe(instr: A.Instruction) -> str:
    """The mnemonic of an instruction, for messages."""
    return type(instr).__name__.upper() if not hasattr(instr, "op") else instr.op


@dataclass
class Structure:
    """The structure of one rung (`build`); `problems` lists its structure errors."""

    rung: A.Rung
    steps: list[Step] = field(default_factory=list)
    problems: list[Problem] = field(default_factory=list)
    open_block: int | None = None  # the BLK still open at the end of the rung (an error)

    def problem(self, message: str, pos: A.Pos | None, text: str, expected: str,
                code: Code) -> None:
        self.problems.append(Problem(message, pos, text, expected, code))


def _used_later(ins: list[A.Instruction], k: int) -> bool:
    for nxt in ins[k + 1:]:
        if isinstance(nxt, A.BoolInstr) and nxt.is_load:
            return False
        if isinstance(nxt, _TRANSPARENT) or (isinstance(nxt, A.Grafcet)
                                             and nxt.op not in ("#", "#D")):
            continue
        return True
    return False


def build(rung: A.Rung, max_parens: int = NO_LIMIT, max_stack: int = NO_LIMIT) -> Structure:
    """Run the stack machine over `rung` on structure only (limits from the controller
    profile: parenthesis depth, MPS depth; the ladder view draws without them)."""
    s = Structure(rung)
    ins = rung.instructions
    acc = False  # the accumulator holds a value
    parens: list[int] = []  # the open `(`s
    mps: list[int] = []
    blk: Ref | None = None
    blk_k: int | None = None
    phase = ""

    def need(step: Step) -> None:
        nonlocal acc
        if not acc:
            s.problem(f"{describe(step.instr)} needs a preceding load", step.pos, "",
                      "LD / LDN / LDR / LDF (or BLK) before it", Code.NEEDS_LOAD)
            acc = True  # reported once: the compiler goes on with 0

    for k, instr in enumerate(ins):
        st = Step(k, instr, blk, blk_k, phase, acc, used_later=_used_later(ins, k))
        s.steps.append(st)
        pos = st.pos
        if isinstance(instr, A.BoolInstr):
            if instr.op == "LD":
                acc = True
            else:
                need(st)
        elif isinstance(instr, A.ParenOpen):
            need(st)
            if len(parens) >= max_parens:
                s.problem(f"parentheses nested deeper than {max_parens}", pos, "",
                          f"at most {max_parens} levels", Code.STRUCTURE)
            parens.append(k)
            if instr.operand is None:
                s.problem(f"{instr.op}( needs an operand", pos, "", "a bit or a comparison",
                          Code.STRUCTURE)
        elif isinstance(instr, A.ParenClose):
            if not parens:
                s.problem("')' without a matching '('", pos, ")", "AND( / OR( / XOR( first",
                          Code.UNMATCHED_CLOSE)
                st.ok = False
                continue
            st.opener = parens.pop()
            need(st)
        elif isinstance(instr, A.Stack):
            if instr.op == "MPS":
                need(st)
                if len(mps) >= max_stack:
                    s.problem(f"MPS stack deeper than {max_stack}", pos, "MPS",
                              f"at most {max_stack} MPS without MPP", Code.STRUCTURE)
                mps.append(k)
            elif not mps:
                s.problem(f"{instr.op} without a preceding MPS", pos, instr.op, "MPS first",
                          Code.NO_MPS)  # the accumulator stays as it was
            else:
                st.opener = mps[-1] if instr.op == "MRD" else mps.pop()
                acc = True
        elif isinstance(instr, A.Blk):
            if blk is not None:
                s.problem("BLK inside a BLK", pos, "BLK", "END_BLK first", Code.STRUCTURE)
            if not instr.block.is_block:
                s.problem(f"BLK {instr.block}: not a function block", pos, str(instr.block),
                          _BLK_HINT, Code.BLOCK)
                st.ok = False
                continue
            blk, blk_k, phase, acc = instr.block, k, "in", False
            st.block, st.block_k = blk, blk_k
        elif isinstance(instr, A.OutBlk):
            if blk is None:
                s.problem("OUT_BLK outside a BLK ... END_BLK block", pos, "OUT_BLK",
                          "BLK %TMi (or another block) before it", Code.OUTSIDE_BLK)
                st.ok = False
                continue
            phase, acc = "out", False
        elif isinstance(instr, A.EndBlk):
            if blk is None:
                s.problem("END_BLK without BLK", pos, "END_BLK", "BLK before it",
                          Code.OUTSIDE_BLK)
                st.ok = False
                continue
            blk, blk_k, phase, acc = None, None, "", False
        elif isinstance(instr, READS_ACC):
            need(st)
    if parens:
        s.problem("'(' not closed before the end of the rung", s.steps[parens[-1]].pos, "",
                  "')'", Code.NOT_CLOSED)
    if blk is not None:
        s.open_block = blk_k
        s.problem(f"BLK {blk} not closed", ins[0].pos if ins else None, "", "END_BLK",
                  Code.NOT_CLOSED)
    return s


# Rung-structure problems that a skipped (syntax error) line can cause further down: those
# looking back for an opening instruction, and those looking forward for a closing one.
_NEEDS_EARLIER = frozenset({Code.NEEDS_LOAD, Code.UNMATCHED_CLOSE, Code.NO_MPS,
                            Code.OUTSIDE_BLK, Code.AFTER_OUT_BLK})
_NEEDS_LATER = frozenset({Code.NOT_CLOSED})


def syntax_follow_ups(partial: A.Program, syntax: list, semantic: list) -> set:
    """Semantic diagnostics that only restate a syntax error: those on a bad line (it holds
    placeholders), an opening missing since the last load because a bad line stood there,
    and a closing missing because the bad line after it in the rung was the closing."""
    bad = {d.line for d in syntax}
    lines = partial.source.splitlines()

    def is_load(n: int) -> bool:
        words = lines[n - 1].split() if 0 < n <= len(lines) else []
        return n not in bad and bool(words) and words[0].upper().startswith(("LD", "BLK"))

    ends = {}
    for r in partial.rungs:
        for n in range(r.first_line, r.last_line + 1):
            ends[n] = r.last_line
    out = set()
    for d in semantic:
        if d.line in bad:
            out.add(d)
        elif d.code in _NEEDS_EARLIER:
            n = d.line - 1
            while n > 0 and not is_load(n):
                if n in bad:
                    out.add(d)
                    break
                n -= 1
        elif d.code in _NEEDS_LATER:
            end = ends.get(d.line, d.line)
            if any(d.line < b <= end + 1 for b in bad):
                out.add(d)
    return out
