"""The resolve pass: what a program uses, checked before any code is generated.

Like CPython's symbol table before code generation, one walk over the AST collects the
function blocks, I/O channels, labels, subroutines, Grafcet steps and edge instructions of
a program and checks the rules about them (labels defined once and within the profile, a
jump stays in its program or subroutine, called subroutines exist, steps within %X). The
PLC allocates blocks, I/O copies and edge memory from the result; code generation only
emits code.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

from softplc.errors import Code, Diagnostic
from softplc.il import ast as A
from softplc.twido.address import ANALOG_KINDS, BLOCK_FIELDS, IO_KINDS, NETWORK_KINDS, Ref

EDGE_MODIFIERS = ("R", "F")


@dataclass
class Resolved:
    """What a program uses. Positions are those of the first use (for diagnostics)."""

    blocks: dict[Ref, A.Pos] = field(default_factory=dict)  # Ref(kind, index)
    io: dict[Ref, A.Pos] = field(default_factory=dict)  # %I / %Q objects and bit strings
    labels: dict[str, dict[int, A.Pos]] = field(default_factory=dict)  # function -> labels
    subroutines: tuple[int, ...] = ()
    edges: int = 0  # edge instructions (LDR, ANDF, AND(R ...): one memory cell each
    initial_steps: tuple[int, ...] = ()
    grafcet: bool = False
    diags: list[Diagnostic] = field(default_factory=list)


def function_name(sr: int | None) -> str:
    return "main" if sr is None else f"SR{sr}"


def _refs(node: object) -> Iterator[tuple[Ref, A.Pos]]:
    """Every address in an operand, expression or statement (iteratively: expressions
    can be deep)."""
    stack = [node]
    while stack:
        n = stack.pop()
        if n is None:
            continue
        pos = getattr(n, "pos", A.NOPOS)
        if isinstance(n, (A.Operand, A.Addr)):
            yield n.ref, pos
        elif isinstance(n, A.Compare):
            stack += [n.left, n.right]
        elif isinstance(n, A.BinOp):
            stack += [n.left, n.right]
        elif isinstance(n, A.Neg):
            stack.append(n.operand)
        elif isinstance(n, A.Call):
            stack += list(n.args)
        elif isinstance(n, A.Assign):
            yield n.target, pos
            stack.append(n.expr)
        elif isinstance(n, A.IncDec):
            yield n.target, pos
        elif isinstance(n, A.ExchCall):  # the table and the port's %MSG block
            yield n.table, pos
            yield Ref("MSG", n.port), pos


def _instruction_refs(instr: A.Instruction) -> Iterator[tuple[Ref, A.Pos]]:
    pos = getattr(instr, "pos", A.NOPOS)
    if isinstance(instr, (A.BoolInstr, A.ParenOpen)):
        yield from _refs(instr.operand)
    elif isinstance(instr, A.Store):
        yield instr.target, pos
    elif isinstance(instr, A.OpBlock):
        yield from _refs(instr.stmt)
    elif isinstance(instr, A.Blk) and instr.block.is_block:
        yield instr.block, pos
    elif isinstance(instr, A.Pin) and instr.block is not None:
        yield instr.block, pos


READ, WRITE, READ_WRITE = "read", "write", "read/write"


def _write_targets(instr: A.Instruction) -> tuple[set[int], set[int]]:
    """ids of the Refs `instr` writes, and of those it both reads and writes."""
    if isinstance(instr, A.Store):
        return {id(instr.target)}, set()
    if isinstance(instr, A.OpBlock):
        stmt = instr.stmt
        if isinstance(stmt, A.Assign):
            return {id(stmt.target)}, set()
        if isinstance(stmt, A.IncDec):
            return set(), {id(stmt.target)}
        if isinstance(stmt, A.ExchCall):  # sent from and answered into the same table
            return set(), {id(stmt.table)}
    return set(), set()


def rung_uses(rung: A.Rung) -> Iterator[tuple[Ref, str, A.Pos]]:
    """Every object a rung reads or writes (block fields and indexes included), with how
    (READ, WRITE or READ_WRITE) and where, in the rung's order."""
    for instr in rung.instructions:
        written, both = _write_targets(instr)
        for ref, pos in _instruction_refs(instr):
            yield ref, WRITE if id(ref) in written else READ_WRITE if id(ref) in both \
                else READ, pos
            if ref.offset is not None:  # %MW2[%MW5]: the index word is read
                yield ref.offset, READ, pos


def object_uses(program: A.Program) -> dict[Ref, tuple[str, A.Pos]]:
    """Every object the program reads or writes (block fields and indexes included): how
    (READ, WRITE or READ_WRITE) and where first, for listings such as the Modbus map."""
    uses: dict[Ref, tuple[str, A.Pos]] = {}
    for rung in program.rungs:
        for ref, role, pos in rung_uses(rung):
            old = uses.get(ref)
            if old is None:
                uses[ref] = (role, pos)
            elif old[0] != role:
                uses[ref] = (READ_WRITE, old[1])
    return uses


def rungs_using(program: A.Program, ref: Ref) -> list[int]:
    """The numbers of the rungs that use `ref`'s object (a block, field or bit of it:
    `LD %TM0.Q` uses %TM0, `CU %C0` uses %C0.V), those that write it first: where an
    object is made."""
    def base(r: Ref) -> Ref:
        return Ref(r.kind, r.index, r.module, r.channel)

    def hits(r: Ref) -> bool:
        return base(r) == base(ref)

    writes, reads = [], []
    for n, rung in enumerate(program.rungs):
        roles = {role for r, role, _ in rung_uses(rung) if hits(r)}
        if roles - {READ}:
            writes.append(n)
        elif roles:
            reads.append(n)
    return writes + reads


class _Resolver:
    def __init__(self, program: A.Program, counts: dict[str, int]):
        self.program = program
        self.counts = counts
        self.out = Resolved()
        self.lines = program.source.splitlines()

    def err(self, code: Code, msg: str, pos: A.Pos | None, text: str = "",
            expected: str = "") -> None:
        p = pos or A.NOPOS
        if not text and 0 < p.line <= len(self.lines):
            text = self.lines[p.line - 1].strip()
        self.out.diags.append(Diagnostic(msg, self.program.file, p.line, p.column, text,
                                         expected, code))

    def run(self) -> Resolved:
        prog, out, counts = self.program, self.out, self.counts
        out.subroutines = tuple(prog.subroutines)
        for n in out.subroutines:
            if n >= counts["SR"]:
                self.err(Code.SUBROUTINE, f"SR{n} beyond the {counts['SR']} subroutines of "
                         f"the profile", A.Pos(prog.subroutine(n)[0].first_line, 1), f"SR{n}:",
                         f"SR0 .. SR{counts['SR'] - 1}")
        self.labels()
        steps = []
        for r in prog.rungs:
            for instr in r.instructions:
                self.instruction(instr, r, steps)
        out.initial_steps = tuple(steps)
        return out

    def labels(self) -> None:
        counts, out = self.counts, self.out
        for r in self.program.rungs:
            if r.label is None:
                continue
            pos = A.Pos(r.label_line or r.first_line, 1)
            if r.label >= counts["L"]:
                self.err(Code.LABEL, f"label %L{r.label} beyond %L{counts['L'] - 1}", pos,
                         f"%L{r.label}:", f"%L0 .. %L{counts['L'] - 1}")
            mine = out.labels.setdefault(function_name(r.subroutine), {})
            if r.label in mine:
                self.err(Code.LABEL, f"label %L{r.label} defined twice", pos,
                         f"%L{r.label}:", "each label defined once")
            else:
                mine[r.label] = pos

    def instruction(self, instr: A.Instruction, rung: A.Rung, steps: list[int]) -> None:
        out, pos = self.out, getattr(instr, "pos", None)
        if isinstance(instr, (A.BoolInstr, A.ParenOpen)) and instr.modifier in EDGE_MODIFIERS:
            out.edges += 1
        for ref, p in _instruction_refs(instr):
            if ref.kind in BLOCK_FIELDS:
                out.blocks.setdefault(Ref(ref.kind, ref.index), p)
            elif ref.kind in IO_KINDS or ref.kind in ANALOG_KINDS or ref.kind in NETWORK_KINDS:
                out.io.setdefault(ref, p)
        if isinstance(instr, A.Jump):
            self.jump(instr, rung)
        elif isinstance(instr, A.SRCall) and instr.number not in out.subroutines:
            self.err(Code.SUBROUTINE, f"SR{instr.number} is called but not defined", pos,
                     f"SR{instr.number}", f"a subroutine 'SR{instr.number}:' after END")
        elif isinstance(instr, A.Grafcet):
            out.grafcet = True
            if instr.op in ("=*=", "-*-") and instr.step is not None:
                if instr.step >= self.counts["X"]:
                    self.err(Code.STEP, f"Grafcet step {instr.step} beyond "
                             f"%X{self.counts['X'] - 1}", pos, str(instr.step),
                             f"0 .. {self.counts['X'] - 1}")
                elif instr.op == "=*=":
                    steps.append(instr.step)

    def jump(self, instr: A.Jump, rung: A.Rung) -> None:
        here = function_name(rung.subroutine)
        if instr.label in self.out.labels.get(here, {}):
            return
        where = next((f for f, labels in self.out.labels.items() if instr.label in labels),
                     None)
        where = {"main": "the main program"}.get(where, where)
        msg = (f"%L{instr.label} is in {where}; a jump cannot leave its program or "
               f"subroutine") if where else f"unknown label %L{instr.label}"
        self.err(Code.LABEL, msg, instr.pos, f"%L{instr.label}",
                 f"a label %L{instr.label}: in the same program or subroutine")


def resolve(program: A.Program, counts: dict[str, int]) -> Resolved:
    """Collect and check what `program` uses (`counts`: the profile's object counts)."""
    return _Resolver(program, counts).run()
