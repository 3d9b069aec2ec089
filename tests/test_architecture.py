"""The shape of the code, checked on its syntax trees (no import, nothing run): no import cycle between the
modules of transcription/ and problems/, the method layer never importing the problems layer, functions a
reader can hold in mind (<= 80 lines) and modules that hold one concept (<= 600 lines), and pyflakes clean.

Imports are read from the whole module, inside functions too (a deferred import is still a dependency);
only those under ``if TYPE_CHECKING:`` are left out (they never run).  A function's length is the lines from
its ``def`` to its last line, docstring and nested functions included.

The limits hold for both layers (problems/ was split into packages by issue 23, its schema by issue 28).
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from support import ROOT

PACKAGE = "se3ocp"
LAYERS = ("transcription", "problems")
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 600

def modules(layer: str) -> dict[str, Path]:
    """{dotted module name: file} of every module below ROOT/layer (a package's __init__ is the package)."""
    out = {}
    for path in sorted((ROOT / layer).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join((PACKAGE,) + parts)] = path
    return out


def _type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or \
        (isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _import_nodes(tree: ast.AST):
    """Every Import/ImportFrom of a module, in functions too, except under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _type_checking(node):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """The modules among ``known`` that module ``name`` (file ``path``) imports."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in _import_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            # `from pkg import name`: the submodule pkg.name if there is one, else pkg itself
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        for t in targets:
            while t and t not in known and "." in t:      # `import a.b.c` of a name inside a module
                t = t.rsplit(".", 1)[0]
            if t in known and t != name:
                out.add(t)
    return out


def import_graph(layers=LAYERS) -> dict[str, set[str]]:
    mods = {k: v for layer in layers for k, v in modules(layer).items()}
    known = set(mods)
    return {name: imports_of(name, path, known) for name, path in mods.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_cycles():
    """The checker itself: a two-module cycle and a three-module one are found, a chain is not."""
    assert cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_imports_inside_functions_count(tmp_path, monkeypatch):
    """A deferred import is a dependency; an import under TYPE_CHECKING is not."""
    f = tmp_path / "m.py"
    f.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .b import X\n"
                 "def g():\n    from .c import Y\n    from . import d\n")
    known = {"p.m", "p.b", "p.c", "p.d"}
    assert imports_of("p.m", f, known) == {"p.c", "p.d"}


def test_no_import_cycle():
    graph = import_graph()
    assert graph, "no modules found"
    assert cycles(graph) == []


def test_transcription_never_imports_problems():
    graph = import_graph()
    bad = {m: sorted(t for t in deps if t.startswith(f"{PACKAGE}.problems"))
           for m, deps in graph.items() if m.startswith(f"{PACKAGE}.transcription")}
    assert not {m: d for m, d in bad.items() if d}


LAYER_PARAMS = list(LAYERS)


def long_functions(path: Path, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    return [f"{path.relative_to(ROOT)}:{n.lineno} {n.name} ({n.end_lineno - n.lineno + 1} lines)"
            for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            and n.end_lineno - n.lineno + 1 > limit]


@pytest.mark.parametrize("layer", LAYER_PARAMS)
def test_functions_fit_in_mind(layer):
    """No function over MAX_FUNCTION_LINES lines."""
    found = [f for path in modules(layer).values() for f in long_functions(path)]
    assert not found, found


@pytest.mark.parametrize("layer", LAYER_PARAMS)
def test_modules_hold_one_concept(layer):
    """No module over MAX_MODULE_LINES lines."""
    found = {str(p.relative_to(ROOT)): n for p in modules(layer).values()
             if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not found, found


def pyflakes_messages(paths, only=None) -> list[str]:
    """pyflakes' messages on ``paths`` (files or folders); ``only``: the message classes to keep (None: all)."""
    from pyflakes import api, reporter

    class Collect(reporter.Reporter):
        def __init__(self):
            super().__init__(None, None)
            self.found = []

        def flake(self, msg):
            if only is None or isinstance(msg, only):
                self.found.append(str(msg))

        def syntaxError(self, filename, msg, lineno, offset, text):
            self.found.append(f"{filename}:{lineno}: {msg}")

        def unexpectedError(self, filename, msg):
            self.found.append(f"{filename}: {msg}")

    rep = Collect()
    api.checkRecursive([str(p) for p in paths], rep)
    return rep.found


def test_no_undefined_names():
    """Every name the code uses is defined (pyflakes): an undefined name on a path the other tests do not
    take -- an error message's formatting, say -- is a traceback for the user who takes it (one was:
    ``_describe`` in the check of a raw ``output_file``)."""
    from pyflakes import messages

    found = pyflakes_messages([ROOT / d for d in ("transcription", "problems", "scripts", "tests")] +
                              [ROOT / "__init__.py"],
                              only=(messages.UndefinedName, messages.UndefinedLocal, messages.UndefinedExport))
    assert not found, found


def test_pyflakes_clean():
    """transcription/, problems/, tests/ and scripts/: no pyflakes message at all (unused imports and variables
    included).  (The package's __init__.py is left out: its names for type checkers look unused to pyflakes.)"""
    found = pyflakes_messages([ROOT / d for d in ("transcription", "problems", "tests", "scripts")])
    assert not found, found


# ------------------------------------------------------------------ the layers of transcription/ (issue 40)
#: the layers of transcription/, lowest first (docs/architecture.md): a module imports its own layer and those
#: before it, never one after it
TRANSCRIPTION_LAYERS = ("compile", "geometry", "outcome", "dynamics", "ocp", "options", "results", "nlp", "methods",
                        "strategy", "objectives", "solve", "closedloop", "")


def transcription_layer(module: str) -> int:
    """The index in TRANSCRIPTION_LAYERS of a module of transcription/ ('' for the package itself)."""
    rest = module[len(f"{PACKAGE}.transcription"):].lstrip(".")
    return TRANSCRIPTION_LAYERS.index(rest.split(".")[0])


def test_every_module_of_transcription_is_in_a_layer():
    for name in modules("transcription"):
        transcription_layer(name)       # raises ValueError for a module outside the layers


def test_no_import_goes_up_a_layer():
    """No module of transcription/ imports one of a later layer (at module level or in a function)."""
    graph = import_graph(("transcription",))
    up = sorted(f"{m} -> {t}" for m, deps in graph.items() for t in deps
                if transcription_layer(t) > transcription_layer(m))
    assert not up, up


#: the upper-case module-level names of methods/ and strategy/ that are not tuning constants: a data layout, a
#: scheme's order, a sentence, CasADi's options (module: names)
NOT_TUNING = {
    "methods.impulsive.sensitivity": {"P_COLS", "P_ROWS_X"},              # index sets of the state layout
    "methods.direct.fatrop": {"NOT_COVERED"},                             # a sentence
    "methods.indirect.conditions": {"LGVI_CONDITIONS"},                   # the conditions, written out
    "methods.indirect.control": {"NB", "NO_NORM", "THRUSTER", "FUEL_EPS"},  # the bound data's layout
    "methods.indirect.switching": {"TINY"},                               # the smallest divisor
    "methods.indirect.shooting": {"MAPACCUM_OPTS"},                       # CasADi's mapaccum options
    "strategy.starts": {"KINDS"},                                         # the starts' names
    "strategy.refine": {"ORDER", "BEST_ORDER"},                           # each scheme's order of accuracy
}


def module_constants(path: Path) -> list[str]:
    """The upper-case names a module assigns at its top level."""
    out = []
    for n in ast.parse(path.read_text(), str(path)).body:
        targets = n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
        for t in targets:
            names = [t] if isinstance(t, ast.Name) else [e for e in getattr(t, "elts", []) if isinstance(e, ast.Name)]
            out += [e.id for e in names if e.id.isupper()]
    return out


@pytest.mark.parametrize("package", ["methods", "strategy"])
def test_no_module_level_tuning_constant(package):
    """methods/ and strategy/ assign no upper-case module-level name but the facts of NOT_TUNING: an algorithm's
    parameters are dataclass fields or arguments that callers and tests set, not globals to patch."""
    prefix = f"{PACKAGE}.transcription."
    found = [f"{name}.{c}" for name, path in modules(f"transcription/{package}").items()
             for c in module_constants(path) if c not in NOT_TUNING.get(name[len(prefix):], set())]
    assert not found, found


def test_every_package_is_installed():
    """pyproject.toml lists the packages a non-editable install copies (the root is the package se3ocp): every
    directory of the two layers with an __init__.py is in the list (transcription/objectives was missing from it, so
    `pip install .` gave a se3ocp that could not import its objectives), and nothing else."""
    tomllib = pytest.importorskip("tomllib")
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {PACKAGE} | {".".join((PACKAGE,) + init.parent.relative_to(ROOT).parts)
                         for layer in LAYERS for init in (ROOT / layer).rglob("__init__.py")}
    assert listed == found, (sorted(found - listed), sorted(listed - found))


#: the import name of each run-time dependency (pyproject.toml's ``dependencies``)
DISTRIBUTION_OF = {"casadi": "casadi", "numpy": "numpy", "matplotlib": "matplotlib", "mpl_toolkits": "matplotlib",
                   "yaml": "pyyaml", "jinja2": "jinja2", "PIL": "pillow", "scipy": "scipy"}
#: the optional extras' packages and the one module each may be imported in (inside a function: only its feature
#: needs it, and says what to install when missing)
OPTIONAL = {"distributed": "problems/sweep/executors.py", "Basilisk": "problems/flight/basilisk.py"}


def test_every_import_is_a_run_time_dependency_or_an_extra_where_it_is_used():
    """Every third-party package the two layers import is one of pyproject.toml's run-time dependencies, or an
    optional extra imported only inside a function of its own module (:data:`OPTIONAL`): scipy, imported by the
    saddle check of every solve, was a test-only dependency, so a fresh `pip install .` could not even validate a
    file."""
    import re
    import sys
    tomllib = pytest.importorskip("tomllib")
    declared = {re.split(r"[<>=\[ ;]", d, maxsplit=1)[0].lower()
                for d in tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]}
    bad = {}
    for layer in LAYERS:
        for path in (ROOT / layer).rglob("*.py"):
            tree, where = ast.parse(path.read_text()), str(path.relative_to(ROOT))
            top_level = set(map(id, tree.body))
            for node in ast.walk(tree):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
                for top in {n.split(".")[0] for n in names} - set(sys.stdlib_module_names) - {"__future__"}:
                    extra = OPTIONAL.get(top) == where and id(node) not in top_level
                    if DISTRIBUTION_OF.get(top) not in declared and not extra:
                        bad.setdefault(top, []).append(where)
    assert not bad, bad
