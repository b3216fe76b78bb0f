"""`softplc verify PROGRAM.il --config X.toml --require REQ.toml`: prove requirements for
every input sequence, or show the scans that break one (replayed in the engine)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from softplc.commands._args import add_program_arguments, existing_file, load_plc
from softplc.errors import SoftPLCError
from softplc.verify.defaults import DEPTH, LOOP_BOUND, MARGIN_S, MAX_K, TIMEOUT_S

EXIT_UNPROVEN, EXIT_VIOLATED, EXIT_DISAGREE = 1, 2, 3
Z3_MEMORY_MB = 3000  # SOFTPLC_Z3_MEMORY_MB overrides (tests give a small one)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "verify", help="prove requirements (interlocks, responses) or find a counterexample",
        description="Check requirements of a program for every input sequence with the z3 "
                    "solver: PROVEN (k-induction or Spacer), VIOLATED (a shortest "
                    "counterexample, replayed in the scan engine) or UNKNOWN up to a "
                    "depth. Exit 0 only if every requirement is proven (or, with "
                    "--bounded, holds to the depth).")
    add_program_arguments(p)
    p.add_argument("--require", type=Path, metavar="REQ.toml",
                   help="requirement file ([environment], [[requirement]] check = ...)")
    p.add_argument("--require-expr", action="append", default=[], metavar="TEXT",
                   help="a requirement on the command line, e.g. 'never %%Q0.1 AND %%Q0.2' "
                        "or, with the configuration's symbols, 'never KM2_STAR AND "
                        "KM3_DELTA' (repeatable)")
    p.add_argument("--depth", type=int, default=DEPTH,
                   help="scans searched for a counterexample (default %(default)s)")
    p.add_argument("--max-k", type=int, default=MAX_K,
                   help="largest k tried by k-induction (default %(default)s)")
    p.add_argument("--timeout", type=float, default=TIMEOUT_S,
                   help="seconds per requirement, all of it (model, engines); it ends "
                        f"UNKNOWN then (killed {MARGIN_S:g} s later if a solver call "
                        "overran) (default %(default)s)")
    p.add_argument("--scan-period", metavar="MIN:MAX",
                   help="any scan period from MIN to MAX in each scan (e.g. 10ms:1s; cyclic "
                        "mode), instead of the configured fixed one")
    p.add_argument("--loop-bound", type=int, default=LOOP_BOUND, metavar="N",
                   help="passes of a loop (backward jump) modelled in one scan; a run "
                        "needing more is reported unknown (default %(default)s)")
    p.add_argument("--bounded", action="store_true",
                   help="exit 0 when no requirement is violated within --depth scans")
    p.add_argument("--no-spacer", action="store_true",
                   help="no Spacer (IC3/PDR) proof attempt after k-induction")
    p.add_argument("--cex", type=Path, metavar="FILE.json",
                   help="write the counterexamples (softplc replay PROGRAM FILE.json; "
                        "softplc repl --replay FILE.json)")
    p.add_argument("--emit-test", type=Path, metavar="FILE.py",
                   help="write a pytest test per counterexample")
    p.add_argument("--junit", type=Path, metavar="REPORT.xml",
                   help="write the verdicts as a JUnit XML report (one test per requirement)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=run)


def _progress(quiet: bool) -> Any:
    last = [time.monotonic()]  # the first line after a second: short runs print none
    tty = sys.stderr.isatty()

    def show(engine: str, depth: int, seconds: float) -> None:
        now = time.monotonic()
        if quiet or now - last[0] < (0.5 if tty else 2.0):
            return
        last[0] = now
        end = "\r" if tty else "\n"
        print(f"  {engine}: depth {depth}, {seconds:.1f} s", end=end, file=sys.stderr,
              flush=True)
    return show


def table(rows: list[dict[str, Any]], symbols: Any = None) -> str:
    """Inputs per scan | the values the requirement reads; a line of symbols above the
    addresses that have one (`symbols`: the configuration's SymbolTable)."""
    ins = sorted({k for r in rows for k in r["inputs"]})
    vals = list(rows[0]["values"]) if rows else []
    head = ["scan"] + ins + (["|"] if vals else []) + vals
    body = [[str(n)] + [str(r["inputs"].get(k, "")) for k in ins] + (["|"] if vals else [])
            + [str(r["values"][k]) for k in vals] for n, r in enumerate(rows, 1)]
    names = [symbols.name_of(symbols.ref(k)) or "" if symbols is not None and k.startswith("%")
             else "" for k in head]
    lines = ([names] if any(names) else []) + [head] + body
    widths = [max(len(c[i]) for c in lines) for i in range(len(head))]
    return "\n".join("    " + " ".join(c.rjust(w) for c, w in zip(line, widths, strict=True))
                     for line in lines)


def run(args: argparse.Namespace) -> int:
    import z3
    cap = int(os.environ.get("SOFTPLC_Z3_MEMORY_MB", Z3_MEMORY_MB))
    z3.set_param("memory_max_size", cap)  # a clear error, not a machine out of memory
    try:
        return _run(args)
    except z3.Z3Exception as e:
        if "memory" not in str(e):
            raise
        raise SoftPLCError(f"softplc verify: the solver's terms outgrew {cap} MB "
                           "(a loop whose passes depend on inputs, unrolled --loop-bound "
                           "times, is the usual cause: lower --loop-bound)") from None


def _run(args: argparse.Namespace) -> int:
    from softplc.verify.advice import unknown_hints
    from softplc.verify.engines import Limits
    from softplc.verify.guard import check, facts
    from softplc.verify.model import Model
    from softplc.verify.replay import emit_test, replay, write_cex
    from softplc.verify.requirements import check_environment, load_spec

    if args.require is None and not args.require_expr:
        print("softplc verify: give --require REQ.toml or --require-expr TEXT",
              file=sys.stderr)
        return 2
    if args.require is not None:
        existing_file(args.require, "requirements")
    plc = load_plc(args, devices=False)
    spec = load_spec(args.require, args.require_expr, plc.symbols)
    if args.scan_period:
        from softplc.verify.requirements import parse_periods
        try:
            spec.periods = parse_periods(args.scan_period)
        except ValueError as e:
            raise SoftPLCError(f"--scan-period {args.scan_period}: {e}") from None
    from softplc.verify.environment import device_words
    model = Model(plc, spec.reads + [r for r, _ in spec.free],
                  spec.host + [r for r, _ in spec.free], spec.periods, args.loop_bound,
                  spec.held, device_words(args.program, args.config))
    check_environment(spec, model.written, str(args.program))
    period = f"{model.period_us / 1000:g} ms" + (
        f" to {model.longest_us / 1000:g} ms" if model.variable else "")
    print(f"{args.program}: {len(plc.ast.rungs)} rungs, {len(model.vars)} state "
          f"variables, {len(model.inputs)} inputs, scan period {period}")
    for line in model.env.lines(model):  # what the proofs take as given
        print(line)
    from softplc.verify.advice import pinned_inputs
    pinned = pinned_inputs(model, spec)
    if pinned:  # a proof resting on these is a proof about a switch nobody moves
        print(f"  ! the assumptions hold {', '.join(pinned)} in every scan: proofs never "
              "see them change")
    from softplc.verify.junit import Case
    worst, cexs, lemmas, cases = 0, [], [], []
    limits = Limits(args.depth, args.max_k, args.timeout, not args.no_spacer)
    if not args.quiet and sys.stderr.isatty():
        print("  proving the program's own facts (once)...", end="\r", file=sys.stderr)
    t0 = time.monotonic()
    known = facts(model, limits)
    print(f"the program's own facts (Grafcet steps, step flags, constant words): "
          f"{len(known)} proven in {time.monotonic() - t0:.1f} s, assumed by every requirement")
    for req in spec.requirements:
        watch = list(dict.fromkeys(str(r) for r in req.reads))
        res = check(model, spec, req, lemmas, limits, watch, _progress(args.quiet))
        if not args.quiet and sys.stderr.isatty():
            print(" " * 50, end="\r", file=sys.stderr)
        if res.status == "PROVEN":
            print(f"PROVEN    {req.name}: {res.method}, {res.seconds:.1f} s")
            cases.append(Case(req.name, "PROVEN", res.seconds))
            if req.kind == "always":  # a lemma for the requirements after it
                lemmas.append(req.cond)
            _vacuity(model, spec, req, limits, args.loop_bound)
            continue
        if res.status == "UNKNOWN":
            note = "; Spacer finds it can fail later (raise --depth, or a scan_period " \
                "range)" if res.method.startswith("Spacer") else ""
            print(f"UNKNOWN   {req.name}: no violation within {res.depth} scans, no proof "
                  f"({res.seconds:.1f} s){note}")
            if res.note:
                print(f"    {res.note}")
            tips = unknown_hints(model, res, limits)
            for tip in tips:
                print(f"    try: {tip}")
            ok = args.bounded and res.depth >= args.depth
            cases.append(Case(req.name, "UNKNOWN", res.seconds,
                              f"no violation within {res.depth} scans, no proof",
                              "\n".join([res.note, *tips]).strip(), ok))
            worst = max(worst, 0 if ok else EXIT_UNPROVEN)
            continue
        print(f"VIOLATED  {req.name}: counterexample of {res.depth} scan(s) from a cold "
              f"start ({res.seconds:.1f} s)")
        shown = table(res.trace, plc.symbols)
        print(shown)
        cases.append(Case(req.name, "VIOLATED", res.seconds,
                          f"counterexample of {res.depth} scan(s)", shown))
        with type(plc).from_file(args.program, args.config, devices=False) as again:
            diffs = replay(again, res.trace)
        if diffs:
            print("  !!! ENGINE AND MODEL DISAGREE on this counterexample: a bug in the "
                  "verifier's model or in the scan engine; please report it:")
            for d in diffs[:10]:
                print(f"  !!! {d}")
            worst = max(worst, EXIT_DISAGREE)
        else:
            print("  replayed in the scan engine: same values in every scan")
            worst = max(worst, EXIT_VIOLATED)
        cexs.append({"requirement": req.name, "check": req.text, "scans": res.trace})
    try:
        if cexs and args.cex:
            write_cex(args.cex, args.program, args.config, cexs)
            cfg = f" --config {args.config}" if args.config else ""
            print(f"counterexamples written to {args.cex} (on the ladder: softplc replay "
                  f"{args.program}{cfg} {args.cex} --web 0; in the debugger: softplc repl "
                  f"{args.program}{cfg} --replay {args.cex})")
        if args.junit:
            from softplc.verify.junit import write
            write(args.junit, str(args.program), cases)
            print(f"JUnit report written to {args.junit}")
        if cexs and args.emit_test:
            emit_test(args.emit_test, args.program, args.config, cexs, plc.symbols)
            print(f"pytest test written to {args.emit_test}")
    except OSError as e:
        raise SoftPLCError(f"cannot write {e.filename}: {e.strerror}") from None
    return worst


def _vacuity(model: Any, spec: Any, req: Any, limits: Any, loop_bound: int) -> None:
    """Flag a proof that rests on objects held at their cold-start value."""
    from softplc.verify.advice import vacuity
    keys, cex = vacuity(model, spec, req, limits, loop_bound)
    if cex is not None:
        print(f"    ! VACUOUS: holds only because {', '.join(keys)} never change (held at "
              f"the cold-start value); free, it fails after {cex.depth} scan(s)")
    elif keys:
        print(f"    note: the proof reads {', '.join(keys)}, held at the cold-start value")
