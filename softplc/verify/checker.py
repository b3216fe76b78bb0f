"""A requirement over a model: its monitor, what holds in a state, what the solver may
assume. Requirement expressions and the response monitor are written once over a value
domain (`semantics.IntDomain` to replay, `symbolic.Z3Domain` to verify)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import z3

from softplc.twido.address import BOOL, Ref
from softplc.twido.semantics import IntDomain
from softplc.verify import floats
from softplc.verify.model import Model, sort_of
from softplc.verify.requirements import FLOAT, Node, Requirement, Spec
from softplc.verify.symbolic import Z3Domain, as_bool, substitute_all, wide

CMP: dict[str, Callable[[Any, Any], Any]] = {
    "=": lambda a, b: a == b, "<>": lambda a, b: a != b, "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, ">=": lambda a, b: a >= b}
FLOAT_LEAVES = {z3.Z3_FLOATING_POINT_SORT, z3.Z3_ROUNDING_MODE_SORT}
# the engines' solver where the cone has floats: z3's QF_FPBV tactic (floats bit-blasted
# afresh at each check) answers the float requirements of tests/integration/
# test_verify_floats.py about 10 times faster than the incremental solver's float theory
FLOAT_TACTIC = "qffpbv"


def evaluate(D: Any, n: Node, read: Callable[[Ref], Any]) -> Any:
    """A requirement expression's value; words exact (no wrap-around), floats doubles
    (`_float`)."""
    op, a = n.op, n.args
    if op == "addr":
        return read(a[0])
    if n.type == FLOAT or op.startswith("cmp:") and a[0].type == FLOAT:
        return _float(D, n, read)
    if op in ("num", "bool"):
        return a[0] if D is IntDomain else (z3.BoolVal(bool(a[0])) if op == "bool"
                                            else wide(a[0]))
    if op == "not":
        return D.not_(evaluate(D, a[0], read))
    if op in ("and", "or"):
        f = D.and_ if op == "and" else D.or_
        return f(evaluate(D, a[0], read), evaluate(D, a[1], read))
    x, y = (evaluate(D, c, read) for c in a[:2]) if len(a) > 1 else (None, None)
    if op == "xor":
        return x != y
    if op.startswith("cmp:"):
        if a[0].type == BOOL and D is IntDomain:
            x, y = int(bool(x)), int(bool(y))
        return CMP[op[4:]](x, y)
    if op == "neg":
        return -evaluate(D, a[0], read)
    if op == "+":
        return x + y
    if op == "-":
        return x - y
    if op == "*":
        return x * y
    q = D.tdiv(x, D.ite(y == 0, 1, y))
    return q if op == "/" else x - q * y


def _float(D: Any, n: Node, read: Callable[[Ref], Any]) -> Any:
    """A float node as the engine computes it: in doubles (a %MF or %KF read is its
    single widened exactly), `+ - *` rounded to nearest-even (Python's floats; z3's RNE
    operations in `floats.binop`), comparisons IEEE's (`compiler/values.py` compiles `[
    %MF0 > 1.0 ]` to Python's `>`: a NaN is unordered, `<>` holds with a NaN, -0.0 =
    0.0), the same rule as the model's (`floats.compare`)."""
    op, a = n.op, n.args
    if op == "num":
        return float(a[0]) if D is IntDomain else floats.const(float(a[0]))
    x = evaluate(D, a[0], read)
    if op == "neg":
        return -x if D is IntDomain else z3.fpNeg(x)
    y = evaluate(D, a[1], read)
    if D is IntDomain:
        return CMP[op[4:]](x, y) if op.startswith("cmp:") else \
            x + y if op == "+" else x - y if op == "-" else x * y
    if op.startswith("cmp:"):
        return floats.compare(op[4:], x, y)
    return floats.binop(op, x, y)[0]  # + - *: no fault (`/` is refused by the parser)


def response_step(D: Any, count: Any, prev: Any, x: Any, y: Any, n: int) -> Any:
    """The response monitor: scans since the oldest unanswered rising edge of x (0: none),
    saturating at n + 1 (the requirement broken)."""
    rising = D.and_(x, D.not_(prev))
    return D.ite(y, 0, D.ite(count > 0, D.ite(count > n, n + 1, count + 1),
                             D.ite(rising, 1, 0)))


class Checker:
    """One requirement on a model: the transition with its monitor, and what must hold."""

    def __init__(self, model: Model, spec: Spec, req: Requirement,
                 lemmas: list[Node] = ()):
        """`lemmas`: invariants already proven for this model (end-of-scan conditions),
        assumed after every scan of the induction step: they strengthen it."""
        self.model, self.spec, self.req = model, spec, req
        self.lemmas = list(lemmas)
        period_us = model.period_us
        self.n = req.within if req.within >= 0 else (-req.within * 1000) // period_us
        self.monitor = req.kind == "response"
        self.keys = {k: v.sort for k, v in model.vars.items()}
        if self.monitor:
            self.keys.update({"_mon": "w16", "_prev": "bool"})
        self.order = list(self.keys)  # the model's invariants are listed in this order
        self.filler: dict[str, Any] = {}  # state outside the cone: its cold-start value
        self.kept: list[int] | None = None  # the model's invariants within the cone
        # a scan from variables (the cone's; with loops, substituted into after: `_scan`)
        self.pre = {k: z3.Const(f"{k}@cone", sort_of(s)) for k, s in self.keys.items()}
        self.inp = self.model.fresh("cone")[1]
        self.post: dict[str, Any] | None = None
        self.lemma_ids: list[int] = []  # `candidates` proven inductive (`lemmas.houdini`)
        self.timer_pairs: list[tuple[str, str]] | None = None  # `invariants.related_pairs`
        self.proven: list[Any] = []  # the model's proven facts over the cone (`stateinv`)
        self.floats = False  # the cone has float terms (`_slice`)
        self._slice()

    def _slice(self) -> None:
        """Keep only the cone of influence: the state the requirement, the assumptions and
        what that state's next values read, to a fixpoint (lemmas reading only that state
        are kept). The rest never influences them: its value is left at the cold start's
        (the engines' terms and Spacer's `Inv` get smaller)."""
        pre, inp = self.pre, self.inp
        names = {f"{k}@cone": k for k in pre}
        post = self.step(pre, inp)
        leaves: set[int] = set()
        need = _reads(z3.And(self.holds(post), *self.assumed(post, inp)), names, leaves)
        work = list(need)
        while work:
            for d in _reads(post[work.pop()], names, leaves) - need:
                need.add(d)
                work.append(d)
        # every float term has a float or rounding-mode leaf (`floats`: values, reads)
        self.floats = bool(leaves & FLOAT_LEAVES)
        # a lemma on other state would only widen the cone (and Spacer's `Inv`)
        self.lemmas = [n for n, t in zip(self.lemmas, self.lemma_terms(post), strict=True)
                       if _reads(t, names) <= need]
        init = self.init()
        invs = self.model.invariants(pre)
        self.kept = [i for i, t in enumerate(invs) if _reads(t, names) <= need]
        self.filler = {k: init[k] for k in self.keys if k not in need}
        self.keys = {k: s for k, s in self.keys.items() if k in need}
        if self.post is not None and self.filler:  # the state outside the cone put in
            self.post = substitute_all(self.post,
                                       [(self.pre[k], v) for k, v in self.filler.items()])
        self.pre = {k: v for k, v in self.pre.items() if k in need}

    def solver(self) -> z3.Solver:
        """A solver for the engines' queries (BMC, k-induction, the range invariants)."""
        return z3.Tactic(FLOAT_TACTIC).solver() if self.floats else z3.Solver()

    def read(self, st: dict[str, Any]) -> Callable[[Ref], Any]:
        m = self.model

        def read(ref: Ref) -> Any:
            m.st, m.inp = st, st
            if ref.type == BOOL:
                return m.read_bit(ref, None)
            return m.read_word(ref, None)[0]
        return read

    def holds(self, post: dict[str, Any]) -> Any:
        """What the requirement needs of the state after a scan; with loops, also that
        none ran past the passes unrolled (such a scan is not modelled: `bmc` reports it
        as unknown, never as a violation)."""
        if self.monitor:
            ok = z3.ULE(post["_mon"], self.n)
        else:
            ok = as_bool(evaluate(Z3Domain, self.req.cond, self.read(post)))
        return z3.And(ok, z3.Not(post["_loop"])) if "_loop" in post else ok

    def assumed(self, post: dict[str, Any], inp: dict[str, Any]) -> list[Any]:
        out = self.model.input_constraints(inp)
        if "_facts" in post:  # abstracted float functions: what is known of their values
            out.append(post["_facts"])
        for a in self.spec.assumptions:
            out.append(as_bool(evaluate(Z3Domain, a, self.read(post))))
        return out

    def lemma_terms(self, post: dict[str, Any]) -> list[Any]:
        return [as_bool(evaluate(Z3Domain, n, self.read(post))) for n in self.lemmas]

    def state_keys(self) -> dict[str, str]:
        """The state in the cone of influence (`_slice`): key -> sort."""
        return dict(self.keys)

    def init(self) -> dict[str, Any]:
        st = self.model.init_state()
        if self.monitor:
            st.update({"_mon": z3.BitVecVal(0, 16), "_prev": z3.BoolVal(False)})
        return {k: v for k, v in st.items() if k in self.keys}

    def step(self, pre: dict[str, Any], inp: dict[str, Any]) -> dict[str, Any]:
        post = self._scan(pre, inp)
        if self.monitor:
            rd = self.read(post)
            x = as_bool(evaluate(Z3Domain, self.req.cond, rd))
            y = as_bool(evaluate(Z3Domain, self.req.target, rd))
            c = response_step(Z3Domain, wide(pre["_mon"]), pre["_prev"], x, y, self.n)
            post["_mon"] = z3.simplify(z3.Extract(15, 0, c))
            post["_prev"] = x
        return post

    def _scan(self, pre: dict[str, Any], inp: dict[str, Any]) -> dict[str, Any]:
        """The model's scan from `pre` with inputs `inp`: its scan from variables with
        these put in. With a loop, whose passes the solver decides (seconds each), that
        scan is built once per requirement; without, a scan is cheap, and built afresh
        its terms are the ones the engines were tuned on (BMC's time depends on them)."""
        if not self.model.loops.sites:
            return self.model.scan({**self.filler, **pre}, inp)
        if self.post is None:
            self.post = self.model.scan(dict(self.pre), self.inp)
        if pre is self.pre and inp is self.inp:
            return dict(self.post)
        return substitute_all(self.post, [(v, pre[k]) for k, v in self.pre.items()]
                    + [(v, inp[k]) for k, v in self.inp.items()])

    def invariants(self, st: dict[str, Any]) -> list[Any]:
        out = self.model.invariants({k: st[k] if k in st else self.filler[k]
                                     for k in self.order})
        if self.kept is not None:
            out = [out[i] for i in self.kept]
        if self.monitor:
            out.append(z3.ULE(st["_mon"], self.n + 1))
        if self.lemma_ids:  # the candidate invariants found inductive (`lemmas.houdini`)
            cands = self.candidates(st)
            out += [cands[i] for i in self.lemma_ids]
        return out + self.facts(st)

    def use_facts(self, facts: list[Any]) -> None:
        """Assume the model's facts proven invariant (`stateinv.prove`) that read only the
        cone's state: true in every reachable state of the model, so of the cone."""
        self.proven = [f for f in facts if f.keys <= set(self.keys)]

    def facts(self, st: dict[str, Any]) -> list[Any]:
        """The model's proven facts (`use_facts`) over state `st`."""
        return [f.term(st) for f in self.proven]

    def candidates(self, st: dict[str, Any]) -> list[Any]:
        """The model's candidate invariants (`lemmas`) over the timers in the cone."""
        from softplc.verify.lemmas import timer_candidates
        timers = {n: t for n, t in self.model.timers.items()
                  if all(f"{n}.{f}" in self.keys for f in ("Q", "V", "P", "_in"))}
        out = timer_candidates(st, timers)
        init = self.model.init_state()
        # presets the program never writes keep their configured value
        out += [st[k] == init[k] for k in sorted(self.keys)
                if k.endswith(".P") and k not in self.model.written and k in init]
        if self.monitor and "_prev" in st and all(
                r.kind not in ("I", "IW", "INW") and f"{r}" in self.keys
                for r in _refs_of(self.req.cond)):
            # the trigger's last value is the trigger on the state (it reads no input)
            out.append(st["_prev"] == as_bool(evaluate(Z3Domain, self.req.cond,
                                                        self.read(st))))
        from softplc.verify.invariants import timer_relations
        return out + timer_relations(self, st)


def _reads(term: Any, names: dict[str, str], sorts: set[int] | None = None) -> set[str]:
    """The state keys whose variables (named in `names`) occur in `term`; `sorts`: gets
    the sort kinds of its leaves (variables and values)."""
    out: set[str] = set()
    seen: set[int] = set()
    todo = [term]
    while todo:
        t = todo.pop()
        i = t.get_id()
        if i in seen:
            continue
        seen.add(i)
        if z3.is_const(t):
            k = names.get(t.decl().name())
            if k is not None:
                out.add(k)
            if sorts is not None:
                sorts.add(t.sort_kind())
        else:
            todo.extend(t.children())
    return out


def _refs_of(n: Node) -> list[Ref]:
    """The objects an expression reads."""
    if n.op == "addr":
        return [n.args[0]]
    return [r for a in n.args if isinstance(a, Node) for r in _refs_of(a)]
