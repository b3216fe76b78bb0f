"""Measure the structure rules of CONTRIBUTING.md / issue 22 on softplc/.

Prints, and exits 1 when a rule is broken (`--strict`), or always 0 (default):

- files over 700 lines;
- classes over 25 methods, a method made by a factory (`stop = _engine("stop")`) counted
  too (tables of one method per instruction or grammar rule are exempt: CLASS_ALLOW);
- files that name each block kind (%TM %C %DR %SBR %SC %R %PLS %PWM %FC %VFC %PID): the
  kind in a string literal or an identifier, outside comments, docstrings and sentences
  (so a format "%TM{i}", a regex alternation, a dict key, a `kind == "PLS"` test, a
  `blocks["TM"]` or a `_configure_pid` all count; the example in a message or a help
  text, "a full address such as %TM0.Q", does not: a string with a space is a sentence).
  A one-letter kind (C, R) alone in a string is a pin or a field as often ("R" resets), so
  it counts only where a kind goes (compared with a `kind`, a key of `blocks`, the first
  argument of `family(...)`, `Family(...)` or `count(...)`) or as "%C0", "%R{i}"; no
  identifier counts for it (`r` is the reset pin's method);
- import cycles between files, every import statement counted (module level, inside
  functions, under `if TYPE_CHECKING:`); `from . import sub` is an edge to `sub` only;
- import cycles between the top-level packages and modules of softplc (`runtime`,
  `compiler`, `plc`...: the package graph), from the same imports (the root `softplc`,
  which re-exports the API, left out);
- files of softplc/web/ that reach the PLC object (`.plc` attribute, `PLC` name, or
  an import of softplc.plc);
- imports that run up the layers (LAYERS: a module imports its own layer or lower ones;
  the data path from program text to the front-ends, the machines above the core, the
  command line on top), and imports from one machine into another (only the shared
  G-code reader and the shipped examples' paths serve several machines).

    python tools/check_structure.py [--strict] [--kinds VFC,PLS,...]
"""

from __future__ import annotations

import argparse
import ast
import functools
import importlib.util
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent / "softplc"
MAX_LINES = 700
MAX_METHODS = 25
MAX_KIND_FILES = 2  # its module and the catalog (issue 32)
KINDS = ("TM", "C", "DR", "SBR", "SC", "R", "PLS", "PWM", "FC", "VFC", "PID")
# Tables of one method per instruction or grammar rule (DEVELOPERS.md excepts them).
CLASS_ALLOW = {"Ops", "_ToAST"}
# The layers, lowest first: a module imports from its own layer and lower ones only. A
# module's layer is that of the longest prefix naming it.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("softplc.errors", "softplc.limits"),    # errors; the input limits every reader applies
    ("softplc.modbus_codec",),                # MBAP and word pairs: the server, EXCH, hosts
    ("softplc.twido",),                       # the Twido object model
    ("softplc.il",),                          # program text -> typed AST
    ("softplc.program",),                     # the compiled code's contract
    ("softplc.runtime",),                     # memory image, blocks, scan engine
    ("softplc.compiler", "softplc.ladder"),   # AST -> code; AST -> ladder
    ("softplc.persist",),                     # retained state
    ("softplc.modbus",),                      # the Modbus codec, map and server
    ("softplc.config",),                      # the typed configuration
    ("softplc.blocks",),                      # the basic blocks: runtime, config, verify
    ("softplc.devices",),                     # generic simulated devices
    ("softplc.assembly",),                    # configuration + program -> a machine
    ("softplc.plc", "softplc.testing"),       # the PLC facade, the pytest plugin
    ("softplc.online",),                      # online program change
    ("softplc.plant",),                       # several controllers on one clock (issue 35)
    ("softplc.access", "softplc.verify"),     # the access port; the verifier
    ("softplc.debug", "softplc.web"),         # the front-ends
    ("softplc.daemon", "softplc.fleet"),     # one controller; many in one process
    ("softplc.commands",),
    ("softplc.machines",),                    # the machines' wing, above the core
    ("softplc", "softplc.cli", "softplc.__main__"),
)
MACHINES = "softplc.machines."
# what two machines may share: the G-code reader, where the shipped examples are, the
# lazy exports of their packages
SHARED_MACHINE_LIBS = ("softplc.machines.gcode", "softplc.machines.examples",
                       "softplc.machines.lazy")
# the wing's own modules that name every machine: the package, the device registry
MACHINE_REGISTRY = ("softplc.machines", "softplc.machines.devices")


@functools.cache
def _walk(tree: ast.AST) -> dict[type, list[ast.AST]]:
    """Every node of `tree` by its type (each list in ast.walk's order), walked once: six
    rules read each module's nodes, and six walks of 240 modules were half this tool's
    time (`measure` clears it); each rule then reads only the types it looks at (checking
    every node's type in each rule was a quarter of it). Read from `_fields` directly: a
    quarter faster than ast.walk."""
    out = [tree]
    for node in out:  # breadth-first: the list grows while it is read
        for name in node._fields:
            value = getattr(node, name, None)
            if isinstance(value, ast.AST):
                out.append(value)
            elif isinstance(value, list):
                out.extend(x for x in value if isinstance(x, ast.AST))
    by_type: dict[type, list[ast.AST]] = {}
    for node in out:
        by_type.setdefault(type(node), []).append(node)
    return by_type


def _nodes(tree: ast.AST, *types: type) -> Iterator[Any]:
    """The nodes of `tree` of these types (those of each type in ast.walk's order)."""
    index = _walk(tree)
    for t in types:
        yield from index.get(t, ())


def _docstring_nodes(tree: ast.AST) -> set[int]:
    ids: set[int] = set()
    for node in _nodes(tree, ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef):
        body = node.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                and isinstance(body[0].value.value, str):
            ids.add(id(body[0].value))
    return ids


def _dotted(node: ast.AST) -> list[str] | None:
    """The names of `a.b.c` (a Name, or attributes of one), None for any other shape: most
    nodes `_kind_slots` asks about are these, and unparsing each was most of its time."""
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    parts.append(node.id)
    return parts


def _kind_slots(tree: ast.AST) -> set[int]:
    """The string constants in a place where a kind goes: compared with something named
    `kind`, a subscript of something named `blocks`, the argument of `family` / `count`
    (alone or in a tuple or set there)."""
    def named(node: ast.AST, words: tuple[str, ...]) -> bool:
        parts = _dotted(node)
        if parts is not None:  # `a.b.c`: a word of its text is one of its names
            return any(w in parts for w in words)
        text = ast.unparse(node)  # rarer shapes (a call, a subscript): their text
        return any(re.search(rf"\b{w}\b", text) for w in words)

    out: set[int] = set()
    for node in _nodes(tree, ast.Compare, ast.Subscript, ast.Call):
        places: list[ast.AST] = []
        if isinstance(node, ast.Compare) and any(
                named(n, ("kind",)) for n in [node.left, *node.comparators]):
            places = [node.left, *node.comparators]
        elif isinstance(node, ast.Subscript) and named(node.value, ("blocks",)):
            places = [node.slice]
        elif isinstance(node, ast.Call) and named(node.func, ("family", "Family", "count",
                                                              "get")) \
                and (not isinstance(node.func, ast.Attribute) or node.func.attr != "get"
                     or named(node.func.value, ("blocks",))):
            places = list(node.args[:1])
        for p in places:
            for c in ast.walk(p):
                if isinstance(c, ast.Constant):
                    out.add(id(c))
    return out


def kind_names(tree: ast.AST, kinds: tuple[str, ...] = KINDS) -> set[str]:
    """The block kinds a module names in code (strings outside docstrings, identifiers)."""
    docs = _docstring_nodes(tree)
    slots = _kind_slots(tree)
    found: set[str] = set()
    # in a string: "%PID0", "%C{i}", "PID" alone, or one alternative of a regex
    # ("TM|DR|PLS"); "FC 3/4" (a Modbus function code) or "kill -USR1 PID" (a process id)
    # is not a kind, nor "%R" or "%C" of a date format (a letter follows the kind or not)
    words = {k: re.compile(rf"%{k}(?=[0-9{{])|^%{k}$" if len(k) == 1 else
                           rf"%{k}(?![A-Za-z])|^{k}$|(?:^|\|){k}(?:\||$)|\({k}\||\|{k}\)")
             for k in kinds}
    # a function or class named after the kind (`_configure_pid`, `VfcBlock`)
    ident = {k: re.compile(rf"(?:^|_){k.lower()}(?:_|$)|{k.capitalize()}[A-Z]|^{k}")
             for k in kinds if len(k) > 1}
    if "PID" in ident:  # set_pid: a process
        ident["PID"] = re.compile(r"(?:^|_)pid(?:_|$)(?<!set_pid)|Pid[A-Z]|^PID")
    for node in _nodes(tree, ast.Constant, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and id(node) not in docs and not re.search(r"\s", node.value) \
                and ("%" in node.value or "|" in node.value or node.value in kinds):
            # (each pattern of `words` needs a "%", a "|" or the kind alone)
            for k, rx in words.items():
                if rx.search(node.value) or (id(node) in slots and node.value == k):
                    found.add(k)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            for k, rx in ident.items():
                if rx.search(node.name):
                    found.add(k)
    return found


def family_classes(root: Path) -> dict[str, tuple[str, str]]:
    """kind -> (module, class) of its runtime block, from the catalog of the tree measured
    (none for a tree without one)."""
    path = root / "twido" / "catalog.py"
    if not path.exists():
        return {}
    # data only, importing nothing of softplc: loaded from its file, whatever tree it is in
    spec = importlib.util.spec_from_file_location("_catalog_measured", path)
    cat: Any = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = cat  # a dataclass looks its module up
    try:
        spec.loader.exec_module(cat)
    finally:
        del sys.modules[spec.name]
    return {k: tuple(f.runtime.split(":")) for k, f in cat.FAMILIES.items()}


def class_names(tree: ast.Module, mod: str, is_pkg: bool,
                families: dict[str, tuple[str, str]]) -> set[str]:
    """The kinds whose runtime class `mod` defines or imports by name (the verifier naming a
    timer by `Timer` names the family as surely as by "TM")."""
    found = {k for k, (m, _c) in families.items() if m == mod}
    for st in _nodes(tree, ast.ImportFrom):
        base = mod.split(".")
        target = ".".join(base[: len(base) - st.level + (1 if is_pkg else 0)]
                          + ([st.module] if st.module else [])) if st.level else st.module
        found |= {k for k, (m, c) in families.items()
                  if m == target and any(a.name == c for a in st.names)}
    return found


def methods(tree: ast.Module) -> list[tuple[str, int, int]]:
    """Methods per class: its defs, and `name = maker(...)` where `maker` is a function of
    the module returning a Callable (a method declared by a factory counts as one)."""
    makers = {f.name for f in tree.body if isinstance(f, ast.FunctionDef) and f.returns
              and "Callable" in ast.unparse(f.returns)}
    out = []
    for node in _nodes(tree, ast.ClassDef):
        n = sum(isinstance(b, (ast.FunctionDef, ast.AsyncFunctionDef)) or (
            isinstance(b, ast.Assign) and isinstance(b.value, ast.Call)
            and isinstance(b.value.func, ast.Name) and b.value.func.id in makers)
            for b in node.body)
        out.append((node.name, node.lineno, n))
    return out


def _module_name(path: Path, root: Path = ROOT) -> str:
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(tree: ast.Module, mod: str, is_pkg: bool, modules: set[str]) -> set[str]:
    """Every import of a softplc module, wherever the statement is: module level, inside a
    function, under `if TYPE_CHECKING:` (a reader of the code sees each one as a
    dependency)."""
    out: set[str] = set()
    for st in _nodes(tree, ast.Import, ast.ImportFrom):
        if isinstance(st, ast.Import):
            out.update(a.name for a in st.names if a.name.startswith("softplc"))
        elif isinstance(st, ast.ImportFrom):
            if st.level:
                base = mod.split(".")
                base = base[: len(base) - st.level + (1 if is_pkg else 0)]
                target = ".".join(base + ([st.module] if st.module else []))
            else:
                target = st.module or ""
            if target.startswith("softplc"):
                # `from . import sub` imports the module sub (the package is
                # being initialised already); `from .m import x` imports m
                subs = {f"{target}.{a.name}" for a in st.names} & modules
                out.update(subs)
                if len(subs) < len(st.names):
                    out.add(target)
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]
    sys.setrecursionlimit(10000)

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(graph):
        if v not in index:
            strong(v)
    return out


@dataclass
class Report:
    """What `measure` found; each list holds one printable line per finding."""

    long_files: list[str] = field(default_factory=list)
    big_classes: list[str] = field(default_factory=list)
    per_kind: dict[str, list[str]] = field(default_factory=dict)
    cycles: list[list[str]] = field(default_factory=list)
    package_cycles: list[list[str]] = field(default_factory=list)
    web_reach: list[str] = field(default_factory=list)
    upward: list[str] = field(default_factory=list)

    @property
    def broken(self) -> int:
        return len(self.long_files) + len(self.big_classes) + len(self.cycles) + len(
            self.package_cycles) + len(self.web_reach) + len(self.upward) + sum(
            len(v) > MAX_KIND_FILES for v in self.per_kind.values())


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The module graph folded onto softplc's top-level packages and modules (`softplc.a.b`
    -> `softplc.a`); the root package, which re-exports the API, is left out."""
    def top(module: str) -> str | None:
        parts = module.split(".")
        return ".".join(parts[:2]) if len(parts) > 1 else None

    out: dict[str, set[str]] = {}
    for m, deps in graph.items():
        if (u := top(m)) is not None:
            out.setdefault(u, set()).update(
                v for d in deps if (v := top(d)) is not None and v != u)
    return out


def layer_of(module: str) -> int:
    """The index in LAYERS of `module` (the longest prefix that names it)."""
    best, depth = len(LAYERS) - 1, -1
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > depth:
                best, depth = i, len(p)
    return best


def machine_of(module: str) -> str | None:
    """The machine package of `module` (softplc.machines.NAME), None for the core."""
    if not module.startswith(MACHINES):
        return None
    return ".".join(module.split(".")[:3])


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """`a -> b` for each import that runs up the layers or from one machine to another."""
    out = []
    for m, deps in sorted(graph.items()):
        for d in sorted(deps):
            mm, md = machine_of(m), machine_of(d)
            across = mm and md and mm != md and md not in SHARED_MACHINE_LIBS \
                and m not in MACHINE_REGISTRY
            if layer_of(d) > layer_of(m) or across:
                out.append(f"{m} -> {d}")
    return out


def measure(root: Path = ROOT, kinds: tuple[str, ...] = KINDS) -> Report:
    rep = Report(per_kind={k: [] for k in kinds})
    families = family_classes(root)
    trees: dict[str, tuple[ast.Module, bool]] = {}
    for path in sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts):
        text = path.read_text()
        rel = str(path.relative_to(root.parent))
        tree = ast.parse(text)
        n_lines = text.count("\n")
        if n_lines > MAX_LINES:
            rep.long_files.append(f"{rel} {n_lines}")
        for name, line, n in methods(tree):
            if n > MAX_METHODS and name not in CLASS_ALLOW:
                rep.big_classes.append(f"{rel}:{line} {name} {n}")
        mod, is_pkg = _module_name(path, root), path.name == "__init__.py"
        named = kind_names(tree) | class_names(tree, mod, is_pkg, families)
        for k in sorted(named & set(kinds)):
            rep.per_kind[k].append(rel)
        trees[mod] = (tree, is_pkg)
        if path.parent.name == "web" and re.search(
                r"\.plc\b|\bPLC\b|softplc\.plc\b|from \.\.plc\b", text):
            rep.web_reach.append(rel)
    known = set(trees)
    graph = {m: _imports(t, m, pkg, known) for m, (t, pkg) in trees.items()}
    inner = {m: {t for t in deps if t in known and t != m} for m, deps in graph.items()}
    rep.cycles = cycles(inner)
    rep.package_cycles = cycles(package_graph(inner))
    rep.upward = upward_imports(inner) if root == ROOT else []
    _walk.cache_clear()  # the trees go with the report (an exception: the next call)
    return rep


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--strict", action="store_true", help="exit 1 when a rule is broken")
    ap.add_argument("--kinds", default=",".join(KINDS), help="block kinds to count")
    args = ap.parse_args(argv)
    rep = measure(kinds=tuple(k for k in args.kinds.split(",") if k))
    print(f"files over {MAX_LINES} lines: {len(rep.long_files)}")
    for x in rep.long_files:
        print("   ", x)
    print(f"classes over {MAX_METHODS} methods: {len(rep.big_classes)}")
    for x in rep.big_classes:
        print("   ", x)
    for k, files in rep.per_kind.items():
        mark = "" if len(files) <= MAX_KIND_FILES else f"  (> {MAX_KIND_FILES})"
        print(f"%{k} named in {len(files)} files{mark}: {' '.join(files)}")
    print(f"import cycles: {len(rep.cycles)}")
    for c in rep.cycles:
        print("   ", " <-> ".join(c))
    print(f"import cycles between packages: {len(rep.package_cycles)}")
    for c in rep.package_cycles:
        print("   ", " <-> ".join(c))
    print(f"web/ files reaching the PLC object: {len(rep.web_reach)} {' '.join(rep.web_reach)}")
    print(f"imports up the layers or across machines: {len(rep.upward)}")
    for x in rep.upward:
        print("   ", x)
    print(f"rules broken: {rep.broken}")
    return 1 if (rep.broken and args.strict) else 0


if __name__ == "__main__":
    raise SystemExit(main())
