"""Compile a parsed program to Python source, once, and exec it.

Fast build: each rung's boolean logic becomes one fused Python expression over the memory
buffers (`_M[5] = _I[3] and not _M[7]`), so the scan loop runs straight-line code with no
per-instruction dispatch. Memory buffers and helpers are bound as default arguments
(LOAD_FAST). Labels split a function into blocks run by a small dispatcher (`_pc`); a
backward jump checks the watchdog so an endless loop ends in HALT, not a hang.

Debug build (`debug=True`): the same code generator with the accumulator materialised
after every instruction and `yield (rung, k)` before instruction k, so the debugger can
step by rung or by instruction and read the power flow (`_log[rung][k]`).
"""
from __future__ import annotations

from typing import Any

from softplc.compiler.resolve import Resolved
from softplc.compiler.values import (
    BLOCK_KIND_PINS,
    BLOCK_OUTPUTS,
    BLOCK_PIN_METHODS,
    ValueCompiler,
    _Acc,
    _Fn,
)
from softplc.errors import Code, CompileError, Diagnostic
from softplc.il import ast as A
from softplc.il import rungtree
from softplc.program import CompiledProgram, Names, ProgramState, Watchdog
from softplc.runtime.codecache import compile_code
from softplc.runtime.grafcet import GRAFCET_BITS
from softplc.twido.address import Ref
from softplc.twido.semantics import COMPARE_PY

MAX_EXPR = 2000  # characters of a fused expression before it is materialised
# CPython compiles one very long function more slowly per line than several shorter ones
# (10,000 rungs in one function: 0.35 s; in parts of ~1,500 lines: 0.2 s): a function body
# longer than twice PART_LINES is cut at rung boundaries into parts it calls in turn
# (10,000 rungs: 19 parts, main() 204 us a scan with or without them).
PART_LINES = 1500
_ENDS = (A.End, A.Return)  # a rung with one may end its function

__all__ = ["CompiledProgram", "Compiler", "Watchdog", "compile_program"]


class Compiler(ValueCompiler):
    """The rung compiler: the boolean accumulator, rungs, program control, functions."""

    def __init__(self, *args: Any, **kw: Any):
        super().__init__(*args, **kw)
        # function name -> body line indices where a rung starts and the function could
        # be cut into parts (none once a rung may return: END/RET would end only a part)
        self.cuts: dict[str, list[int]] = {}

    # ---- boolean operands -----------------------------------------------------------------
    def operand(self, op: A.BoolOperand | None, blk: Ref | None, pos: A.Pos | None) -> str:
        if op is None:
            return "True"
        if isinstance(op, A.Const):  # bits are held as bools: stores write True/False
            return "True" if op.value else "False"
        if isinstance(op, A.Operand):
            return self.read_bit(op.ref, op.pos)
        if isinstance(op, A.BlockOutput):
            if blk is None:
                self.err(f"block output {op.name} outside BLK ... OUT_BLK", op.pos, op.name,
                         "a full address such as %TM0.Q", code=Code.BLOCK)
                return "0"
            outs = BLOCK_OUTPUTS.get(blk.kind, ())
            if op.name not in outs:
                self.err(f"%{blk.kind} has no output {op.name}", op.pos, op.name,
                         ", ".join(outs) or "no output", code=Code.BLOCK)
                return "0"
            return f"({self.block_name(blk)}.{op.name} == 1)"  # a bool: see read_bit
        if isinstance(op, A.Compare):
            a, b = self.operand_pair(op.left, op.right, None)
            if self.unify(a, b, op.pos, "comparison") is None:
                return "0"
            code = f"({a[0]} {COMPARE_PY[op.op]} {b[0]})"
            if "(" in a[0] or "(" in b[0]:  # helpers may set %S18: evaluate exactly once
                t = self.new_tmp()
                self.emit(f"{t} = {code}")
                return t
            return code
        self.err("unsupported operand", pos, "", "a bit, 0/1 or a comparison block",
                 code=Code.OTHER)
        return "0"

    def modified(self, code: str, mod: str) -> _Acc:
        if mod == "N":
            return _Acc(f"(not {code})", neg=code)
        if mod in ("R", "F"):
            edge = Names.EDGE
            self.use(edge)
            k = next(self.edge)
            v, r = self.new_tmp(), self.new_tmp()
            self.emit(f"{v} = {code}")
            self.emit(f"{r} = {v} {'>' if mod == 'R' else '<'} {edge}[{k}]")
            self.emit(f"{edge}[{k}] = {v}")
            return _Acc(r)
        return _Acc(code)

    @staticmethod
    def combine(op: str, left: _Acc, right: _Acc) -> _Acc:
        if op == "XOR":  # != binds tighter than and/or: parenthesise compound operands
            lc = f"({left.code})" if left.kind != "atom" else left.code
            rc = f"({right.code})" if right.kind != "atom" else right.code
            return _Acc(f"({lc} != {rc})")
        if op == "AND" and left.neg is not None and right.neg is not None:
            either = f"{left.neg} or {right.neg}"
            return _Acc(f"(not ({either}))", neg=either)
        if op == "AND":
            lc = f"({left.code})" if left.kind == "or" else left.code
            rc = f"({right.code})" if right.kind == "or" else right.code
            return _Acc(f"{lc} and {rc}", "and")
        return _Acc(f"{left.code} or {right.code}", "or")

    # ---- rungs ----------------------------------------------------------------------------
    def rung(self, rung: A.Rung, ctx: dict[str, Any]) -> None:
        """Emit one rung. ctx carries function-level facts (labels -> blocks, Grafcet step).
        The rung's structure (what each `)`, MRD and MPP refers to, the open BLK, the
        structure errors) comes from `il.rungtree`; here only the code of each value."""
        tree = rungtree.build(rung, self.counts["PAREN"], self.counts["STACK"])
        for p in tree.problems:
            self.err(p.message, p.pos, p.text, p.expected, code=p.code)
        acc: _Acc | None = None
        saved: dict[int, _Acc] = {}  # the accumulator at each `(` and MPS, by instruction
        blk_pins: dict[str, str] = {}
        base_indent = self.indent
        step = ctx.get("step")
        if step is not None:
            self.emit(f"if {Names.STEPS_AT_START}[{step}]:")  # the step bits at the start
            self.indent += 1
            base_indent = self.indent
        body_start = len(self.fn.lines)
        if not rung.instructions:
            self.emit("pass")

        def need() -> _Acc:  # a missing load is reported by the structure pass
            nonlocal acc
            if acc is None:
                acc = _Acc("0")
            return acc

        def run_block(st: rungtree.Step) -> None:  # the block's inputs are all given
            if st.block is None or st.phase != "in":
                return
            pins = BLOCK_KIND_PINS.get(st.block.kind, ())
            args = ", ".join(blk_pins.get(p, "0") for p in pins)
            self.emit(f"{self.block_name(st.block)}.run({args})")

        for st in tree.steps:
            k, instr, pos, blk = st.k, st.instr, st.pos, st.block
            self.ninstr += 1
            if self.debug:
                self.indent = base_indent
                self.emit(f"yield ({rung.index}, {k})")
            if not st.ok:
                continue
            if isinstance(instr, A.BoolInstr):
                code = self.operand(instr.operand, blk, pos)
                val = self.modified(code, instr.modifier)
                if instr.op == "LD":
                    acc = val
                else:
                    acc = self.combine(instr.op, need(), val)
            elif isinstance(instr, A.ParenOpen):
                outer = need()
                if not outer.simple and len(outer.code) > MAX_EXPR // 2:
                    outer = self.materialize(outer)
                saved[k] = outer
                code = self.operand(instr.operand, blk, pos) if instr.operand else "0"
                # the modifier applies to the first operand inside the parenthesis, as
                # LDN/LDR/LDF would [manual, see docs/twido.md#instruction-list]
                acc = self.modified(code, instr.modifier)
            elif isinstance(instr, A.ParenClose):
                op = tree.steps[st.opener].instr.op
                inner = need()
                acc = self.combine(op, saved[st.opener], _Acc(f"({inner.code})")
                                   if inner.kind != "atom" else inner)
            elif isinstance(instr, A.Negate):
                a = need()
                acc = _Acc(f"(not ({a.code}))" if a.kind != "atom" else f"(not {a.code})",
                           neg=a.code)
            elif isinstance(instr, A.Stack):
                if instr.op == "MPS":
                    acc = saved[k] = self.materialize(need())
                elif st.opener is not None:  # else no MPS (reported): acc unchanged
                    acc = _Acc(saved[st.opener].code)
            elif isinstance(instr, A.Store):
                a = need()
                if st.used_later or self.debug:
                    a = acc = self.materialize(a)
                if instr.op == "ST":
                    self.write_bit(instr.target, a.code, pos)
                elif instr.op == "STN":
                    self.write_bit(instr.target, f"not ({a.code})", pos)
                else:
                    if instr.target.is_block:
                        self.err(f"{instr.op} {instr.target} on a block", pos, str(instr.target),
                                 "a bit; a block's inputs are R / S / CU / CD / IN pins",
                                 code=Code.BLOCK)
                        continue
                    value = "True" if instr.op == "S" else "False"
                    if a.code in ("1", "True"):
                        self.write_bit(instr.target, value, pos)
                    elif a.code not in ("0", "False"):
                        self.emit(f"if {a.code}:")
                        self.indent += 1
                        self.write_bit(instr.target, value, pos)
                        self.indent -= 1
            elif isinstance(instr, A.OpBlock):
                a = need()
                if st.used_later or self.debug:
                    a = acc = self.materialize(a)
                cond = a.code not in ("1", "True")
                if cond:
                    self.emit(f"if {a.code}:")
                    self.indent += 1
                self.statement(instr.stmt)
                if cond:
                    self.indent -= 1
            elif isinstance(instr, A.Jump):
                self.jump(instr, acc, ctx, rung)
            elif isinstance(instr, A.SRCall):
                a = need()
                if instr.number not in ctx["subroutines"]:
                    continue  # reported by the resolve pass
                if st.used_later or self.debug:
                    a = acc = self.materialize(a)
                sr = Names.subroutine(instr.number)
                call = f"yield from {sr}()" if self.debug else f"{sr}()"
                self.conditional(a.code, call)
            elif isinstance(instr, A.Return):
                if ctx["function"] == "main":
                    self.err("RET outside a subroutine", pos, instr.op, "END in the main program",
                             code=Code.CONTROL)
                    continue
                self.end_like(instr.op, acc, "RET", "return")
            elif isinstance(instr, A.End):
                if ctx["function"] != "main":
                    self.err(f"{instr.op} inside a subroutine", pos, instr.op, "RET",
                             code=Code.CONTROL)
                    continue
                self.end_like(instr.op, acc, "END", ctx["end_code"])
            elif isinstance(instr, A.Nop):
                pass
            elif isinstance(instr, A.Blk):
                blk_pins = {}
                self.block_name(instr.block)
                acc = None
            elif isinstance(instr, (A.OutBlk, A.EndBlk)):
                run_block(st)
                acc = None
            elif isinstance(instr, A.Pin):
                self.pin(instr, need(), blk, st.phase, blk_pins)
                if st.used_later or self.debug:
                    acc = self.materialize(acc)
            elif isinstance(instr, A.Grafcet):
                self.grafcet(instr, acc, ctx)
            else:  # pragma: no cover - the parser makes no other nodes
                self.err(f"unsupported instruction {instr}", pos, "", "an instruction",
                         code=Code.OTHER)
            if self.debug and acc is not None:
                acc = self.materialize(acc)
                self.use(Names.LOG)
                self.emit(f"{Names.LOG}[{rung.index}][{k}] = {acc.code}")
        if len(self.fn.lines) == body_start:  # e.g. a lone LD in a step: keep `if` valid
            self.indent = base_indent
            self.emit("pass")
        self.indent = base_indent - (1 if step is not None else 0)

    def conditional(self, cond: str, stmt: str) -> None:
        if cond in ("1", "True"):
            self.emit(stmt)
        elif cond not in ("0", "False"):
            self.emit(f"if {cond}:")
            self.emit(f"    {stmt}")

    def end_like(self, op: str, acc: _Acc | None, base: str, code: str) -> None:
        """END/RET (unconditional), ENDC/RETC (if the accumulator is 1), ENDCN/RETCN (if 0)."""
        if op == base:
            self.emit(code)
            return
        if acc is None:
            self.err(f"{op} needs a preceding load", None, op, "LD before it", code=Code.NEEDS_LOAD)
            return
        cond = f"not ({acc.code})" if op.endswith("CN") else acc.code
        self.emit(f"if {cond}:")
        self.emit(f"    {code}")

    def pin(self, instr: A.Pin, acc: _Acc, blk: Ref | None, phase: str,
            pins: dict[str, str]) -> None:
        target = instr.block or blk
        if target is None:
            self.err(f"input {instr.name} outside a BLK and without a block", instr.pos,
                     instr.name, f"BLK ... {instr.name} ... END_BLK, or {instr.name} %C0",
                     code=Code.OUTSIDE_BLK)
            return
        allowed = BLOCK_KIND_PINS.get(target.kind, ())
        if instr.name not in allowed:
            self.err(f"%{target.kind} has no input {instr.name}", instr.pos, instr.name,
                     ", ".join(allowed), code=Code.BLOCK)
            return
        if instr.block is None:  # inside BLK: remember, run at OUT_BLK / END_BLK
            if phase != "in":
                self.err(f"input {instr.name} after OUT_BLK", instr.pos, instr.name,
                         "inputs between BLK and OUT_BLK", code=Code.AFTER_OUT_BLK)
                return
            a = self.materialize(acc)
            pins[instr.name] = a.code
            return
        b = self.block_name(target)
        method = BLOCK_PIN_METHODS[instr.name]
        self.emit(f"{b}.{method}({acc.code})")

    def grafcet(self, instr: A.Grafcet, acc: _Acc | None, ctx: dict[str, Any]) -> None:
        if instr.op in ("=*=", "-*-"):
            return  # step markers are handled by the function generator
        if instr.op == "POST":
            return
        cur = ctx.get("step")
        if cur is None:
            self.err(f"{instr.op} outside a Grafcet step", instr.pos, instr.op,
                     "a step first (=*= i or -*- i)", code=Code.STEP)
            return
        ga, gd = Names.ACTIVATE, Names.DEACTIVATE
        self.use(ga, gd)
        if instr.op == "#":
            stmts = [f"{gd}.append({cur})"] + ([f"{ga}.append({instr.step})"]
                                               if instr.step is not None else [])
        else:  # "#D i": deactivate step i and the current step [manual, unsure]
            stmts = [f"{gd}.append({cur})", f"{gd}.append({instr.step})"]
        code = acc.code if acc is not None else "1"
        if code not in ("1", "True"):
            self.emit(f"if {code}:")
            self.indent += 1
            for s in stmts:
                self.emit(s)
            self.indent -= 1
        else:
            for s in stmts:
                self.emit(s)

    def jump(self, instr: A.Jump, acc: _Acc | None, ctx: dict[str, Any], rung: A.Rung) -> None:
        labels = ctx["labels"]
        if instr.label not in labels:
            return  # reported by the resolve pass
        target = labels[instr.label]
        here = ctx["block_of"][rung.index]
        stmts = [f"_pc = {target}"]
        if target <= here:  # backward: a loop, watch the watchdog
            self.use(Names.WATCHDOG)
            stmts += ["_n += 1", f"if not _n & 1023 and {Names.WATCHDOG}():",
                      f"    raise {Names.WATCHDOG_EXC}()"]
        stmts.append("continue")
        if instr.op == "JMP":
            cond = "1"
        else:
            if acc is None:
                self.err(f"{instr.op} needs a preceding load", instr.pos, instr.op,
                         "LD before it (or JMP, unconditional)", code=Code.NEEDS_LOAD)
                return
            cond = acc.code if instr.op == "JMPC" else f"not ({acc.code})"
        if cond not in ("1", "True"):
            self.emit(f"if {cond}:")
            self.indent += 1
        for s in stmts:
            self.emit(s)
        if cond not in ("1", "True"):
            self.indent -= 1

    # ---- functions ------------------------------------------------------------------------
    def function(self, name: str, rungs: list[A.Rung], ctx: dict[str, Any]) -> _Fn:
        self.fn = fn = _Fn(name)
        labels: dict[int, int] = {}
        block_of: dict[int, int] = {}
        blocks: list[list[A.Rung]] = [[]]
        for r in rungs:
            if r.label is not None:
                if blocks[-1]:
                    blocks.append([])
                labels.setdefault(r.label, len(blocks) - 1)  # a second one is reported
            blocks[-1].append(r)
            block_of[r.index] = len(blocks) - 1
        ctx = dict(ctx, labels=labels, block_of=block_of, function=name,
                   end_code="return" if not ctx.get("grafcet") else
                   f"{Names.GRAFCET_POST}(); return")
        dispatch = any(isinstance(i, A.Jump) for r in rungs for i in r.instructions)
        # a local (_pc, _XS) or a generator spans rungs in these: one function
        cuts = self.cuts[name] = []
        cut = not (dispatch or self.debug or ctx.get("grafcet"))
        self.indent = 1
        if dispatch:
            self.emit("_pc = 0")
            self.emit("_n = 0")
            self.emit("while True:")
            self.indent = 2
        step: int | None = None
        for bi, block in enumerate(blocks):
            if dispatch:
                self.indent = 2
                self.emit(f"if _pc == {bi}:")
                self.indent = 3
            for r in block:
                marker = next((i for i in r.instructions if isinstance(i, A.Grafcet)
                               and i.op in ("=*=", "-*-", "POST")), None) \
                    if ctx.get("grafcet") else None  # any Grafcet instruction sets it
                if marker is not None:
                    if marker.op == "POST" or step is None and name == "main":
                        if step is None:
                            if not ctx.get("pre_done"):  # end of preprocessing:
                                ctx["pre_done"] = True  # %S21-%S23 act here [manual]
                                s = Names.BIT["S"]
                                self.use(Names.GRAFCET_PRE, s)
                                self.emit(" or ".join(f"{s}[{b}]" for b in GRAFCET_BITS)
                                          .join(("if ", ":")))  # rarely set: skip the call
                                self.emit(f"    {Names.GRAFCET_PRE}()")
                            self.use(Names.BIT["X"])
                            self.emit(f"{Names.STEPS_AT_START} = bytes({Names.BIT['X']})")
                    if marker.op == "POST":
                        self.use(Names.GRAFCET_POST)
                        self.emit(f"{Names.GRAFCET_POST}()")
                        step = None
                        ctx["post_done"] = True
                    else:
                        step = marker.step  # beyond %X: reported by the resolve pass
                    if self.debug:
                        self.emit(f"yield ({r.index}, 0)")
                    continue
                if cut:
                    cuts.append(len(fn.lines))
                    cut = not any(isinstance(i, _ENDS) for i in r.instructions)
                self.rung(r, dict(ctx, step=step))
            if dispatch:
                self.indent = 3
                self.emit(f"_pc = {bi + 1}")
        if dispatch:
            self.indent = 2
            self.emit("return")
        if name == "main" and ctx.get("grafcet") and not ctx.get("post_done"):
            self.indent = 1
            self.use(Names.GRAFCET_POST)
            self.emit(f"{Names.GRAFCET_POST}()")
        return fn

    def render(self, fn: _Fn, fname: str) -> list[str]:
        """The function's source: its parts first (each a `def`), then the function."""
        names = sorted(fn.names)
        body = fn.lines or ["    pass"]
        if self.debug and not any("yield" in ln for ln in body):
            body = body + ["    yield from ()"]
        defs: list[str] = []  # the parts, defined before the function that calls them
        parts: list[str] = []
        start = 0
        if len(body) > 2 * PART_LINES:
            for c in self.cuts.get(fn.name, ()):
                if c - start >= PART_LINES and len(body) - c >= PART_LINES // 2:
                    parts.append(f"{fname}_part{len(parts)}")
                    defs.append(_def(parts[-1], names, body[start:c]))
                    start = c
        calls = [f"    {p}()" for p in parts]
        return [*defs, _def(fname, sorted(names + parts), calls + body[start:])]


def _def(fname: str, names: list[str], body: list[str]) -> str:
    """A function with the bound `names` as defaults (LOAD_FAST in the body)."""
    args = ", ".join(f"{n}={n}" for n in names)
    return f"def {fname}({args}):\n" + "\n".join(body) + "\n"


def compile_program(program: A.Program, resolved: Resolved, env: dict[str, Any],
                    state: ProgramState, counts: dict[str, int], debug: bool = False,
                    forced: frozenset[Ref] = frozenset(),
                    diagnostics: list[Diagnostic] = ()) -> CompiledProgram:
    """Generate and exec the program in namespace `env` (see `program.bind`), with edge
    memory and Grafcet transitions in `state`. `resolved` is the resolve pass's result and
    `diagnostics` the problems found allocating what it lists: raises CompileError with
    every problem. Stores to the `forced` bits are left out, so forcing holds all through
    a scan."""
    c = Compiler(program, counts, debug, forced)
    c.env = env
    c.diags.extend(resolved.diags)
    c.diags.extend(diagnostics)
    base_ctx = {"subroutines": set(resolved.subroutines), "grafcet": resolved.grafcet}
    defs: list[str] = []  # one `def` each
    for n in resolved.subroutines:
        fn = c.function(f"SR{n}", program.subroutine(n), dict(base_ctx))
        defs += c.render(fn, Names.subroutine(n))
    fn = c.function("main", program.main, base_ctx)
    defs += c.render(fn, Names.MAIN)
    fn.lines.clear()  # not needed now: the memory goes back before compile() below
    if c.diags:
        uniq = sorted(set(c.diags), key=lambda d: (d.line, d.column, d.message))
        raise CompileError(uniq)
    edges = next(c.edge)
    if edges > resolved.edges:  # the two passes must agree on what is an edge instruction
        raise CompileError(Diagnostic(f"internal: {edges} edge instructions generated, "
                                      f"{resolved.edges} resolved", program.file,
                                      code=Code.OTHER))
    source = "\n".join(defs)
    ns = dict(env)
    if debug:
        ns[Names.LOG] = [[None] * len(r.instructions) for r in program.rungs]
    # def by def, in order (each binds the ones before it): compile() takes more time per
    # line of a longer text (20 defs of 10,000 rungs: 0.28 s in one text, 0.22 one by one)
    for d in defs:
        exec(compile_code(d, f"<softplc:{program.file}>"), ns)
    return CompiledProgram(program, source, ns[Names.MAIN], ns, state, debug,
                           ns.get(Names.LOG, []), c.ninstr)
