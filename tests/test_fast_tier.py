"""The fast tier (``pytest -m "not slow"``) touches every module of tlm.

The tier is the suite less the tests marked ``slow`` (whole-scene renders, sweeps,
studies, subprocess runs): under a minute here, against about eleven for the whole suite
in one process (six to seven in one process per core, as CI runs it), which CI still
runs. A tier that skips a module would let a change to it pass the quick check unseen,
so this test asks, for every ``tlm/**/*.py``, whether some test of the
tier *itself* uses it. It reads the tests' source (``ast``), not a coverage trace
(running the tier under coverage would cost the tier's own time again), and counts
only what a test names:

* which tests are in the tier is pytest's own answer: ``pytest --collect-only -m "not
  slow"`` in a subprocess, so a mark from any source (decorator, ``pytestmark``,
  ``pytest.param(marks=...)``) counts as pytest applies it;
* from each such test function the names it uses are followed, through the test's
  fixtures (by argument name, in its file and the ``conftest.py`` files above it), its
  decorators (parametrize lists) and the helpers, classes and module-level values of
  the tests' own files (``tests.scenes``, ``tests.extreme.util``, ...); a module-level
  ``import`` counts only when a followed name is bound by it, so a file whose tests
  are all slow touches nothing;
* a name imported from tlm touches the module that *defines* the object
  (``obj.__module__``: a function re-exported by a package touches the module it lives
  in), and the module imported from (whose code the import ran); an import inside a
  followed function counts the same way;
* a command line, ``main(["run", ...])`` with ``main`` from :mod:`tlm.cli` or
  ``python -m tlm run ...`` in a subprocess, touches :mod:`tlm.cli` (and
  :mod:`tlm.__main__` for ``-m tlm``) and the modules the subcommand's handler
  imports itself, directly or in the helpers of cli.py it calls: the code that handles
  that subcommand;
* a package's ``__init__`` is touched when a module inside it is (Python runs it
  first).

What tlm's own modules import in turn does *not* count: a module reached only through
another's imports has no test that would fail for a reason of its own. One exception: a
private module (``kernels/_jit.py``) counts through a touched module of its package that
imports it. A call whose arguments the source does not spell (``main([*args])``) is not
followed, so the check errs towards asking for a test, never towards crediting one.
"""

from __future__ import annotations

import ast
import functools
import importlib
import re
import subprocess
import sys
import types
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.conftest import COLLECTED

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "tlm"
TESTS = REPO / "tests"


def tlm_modules(root: Path = PACKAGE) -> list[str]:
    """Every module of the package, dotted (``tlm.kernels.bsp``; a package by its name)."""
    out = []
    for path in sorted(root.rglob("*.py")):
        parts = ("tlm", *path.relative_to(root).with_suffix("").parts)
        out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


@functools.cache
def _is_module(name: str) -> bool:
    rel = PACKAGE.joinpath(*name.split(".")[1:])
    return rel.with_suffix(".py").is_file() or (rel / "__init__.py").is_file()


@functools.cache
def _defining(module: str, attr: str) -> frozenset[str]:
    """The modules ``from module import attr`` touches: ``module`` itself, ``module.attr``
    when that is a module, else the module that defines the object (``__module__``)."""
    if _is_module(f"{module}.{attr}"):
        return frozenset({module, f"{module}.{attr}"})
    try:
        obj = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError):  # a name the package no longer has: the import's module only
        return frozenset({module})
    owner = getattr(obj, "__module__", None) if not isinstance(obj, types.ModuleType) else obj.__name__
    if isinstance(owner, str) and owner.split(".")[0] == "tlm" and _is_module(owner):
        return frozenset({module, owner})
    return frozenset({module})


def _tier(items) -> dict[Path, set[str]]:
    """File -> the qualified names of the test functions with a case that is not marked slow."""
    out: dict[Path, set[str]] = defaultdict(set)
    for item in items:
        if item.get_closest_marker("slow") is None:
            out[Path(item.path).resolve()].add(item.nodeid.partition("::")[2].split("[", 1)[0].replace("::", "."))
    return out


def fast_tests(session: pytest.Session | None = None, tests: Path = TESTS) -> dict[Path, set[str]]:
    """The tier's test functions, as pytest selects them with ``-m "not slow"``: file ->
    qualified names (a parametrized function once, when any of its cases is in the tier).

    From this session's own collection when it holds every test file (tests/conftest.py
    keeps it before ``-m``/``-k`` deselect anything), else from ``pytest --collect-only
    -m "not slow"`` in a subprocess (running this file alone, say).
    """
    items = session.stash.get(COLLECTED, None) if session is not None else None
    every = {p.resolve() for p in tests.rglob("test_*.py")}
    if items is not None and every <= {Path(i.path).resolve() for i in items}:
        return _tier(items)
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                           "-m", "not slow", str(tests)], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out: dict[Path, set[str]] = defaultdict(set)
    for line in done.stdout.splitlines():
        if "::" in line:
            file, _, rest = line.partition("::")
            out[(REPO / file).resolve()].add(rest.split("[", 1)[0].replace("::", "."))
    return out


@dataclass
class _File:
    """One file of code read for names: its top-level definitions and what its imports bind."""

    path: Path
    module: str
    defs: dict[str, list[ast.AST]] = field(default_factory=dict)
    tlm_names: dict[str, frozenset[str]] = field(default_factory=dict)  # name -> the tlm modules using it touches
    tlm_modules: dict[str, str] = field(default_factory=dict)  # name bound to a tlm module
    test_names: dict[str, tuple[str, str | None]] = field(default_factory=dict)  # name -> (tests module, attr)
    cli_main: set[str] = field(default_factory=set)  # names bound to tlm.cli.main


def _module_name(path: Path, root: Path, top: str) -> str:
    parts = (top, *path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _resolve(base: str, node: ast.ImportFrom, path: Path) -> str:
    """The absolute module of ``from ... import`` in the module ``base`` (``path``)."""
    if not node.level:
        return node.module or ""
    package = base if path.name == "__init__.py" else base.rpartition(".")[0]
    parts = package.split(".")[: len(package.split(".")) - (node.level - 1)]
    return ".".join([*parts, *([node.module] if node.module else [])])


def _read(path: Path, module: str) -> _File:
    f = _File(path, module)
    for node in ast.parse(path.read_text(), str(path)).body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            f.defs.setdefault(node.name, []).append(node)
        elif isinstance(node, ast.Assign | ast.AnnAssign | ast.AugAssign):
            for t in node.targets if isinstance(node, ast.Assign) else [node.target]:
                for n in ast.walk(t):
                    if isinstance(n, ast.Name):
                        f.defs.setdefault(n.id, []).append(node)
        elif isinstance(node, ast.Import):
            for a in node.names:
                root = a.name.split(".")[0]
                if root == "tlm":  # ``import tlm.x.y`` binds ``tlm``: the attribute chain names the module
                    f.tlm_modules[a.asname or "tlm"] = a.name if a.asname else "tlm"
                elif root == "tests":
                    f.test_names[a.asname or "tests"] = (a.name if a.asname else "tests", None)
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, node, path)
            for a in node.names:
                name = a.asname or a.name
                if target.split(".")[0] == "tlm":
                    if _is_module(f"{target}.{a.name}"):
                        f.tlm_modules[name] = f"{target}.{a.name}"
                    else:
                        f.tlm_names[name] = _defining(target, a.name)
                        if target == "tlm.cli" and a.name == "main":
                            f.cli_main.add(name)
                elif target.split(".")[0] == "tests":
                    f.test_names[name] = (target, a.name)
    return f


def _is_fixture(node: ast.AST) -> bool:
    return any("fixture" in ast.unparse(d) for d in getattr(node, "decorator_list", ()))


def _locals(node: ast.AST, every: list[ast.AST]) -> set[str]:
    """The names a function binds itself (arguments, assignments, loop and ``with`` targets);
    ``every`` is ``list(ast.walk(node))``."""
    if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
        return set()
    return {n.arg for n in every if isinstance(n, ast.arg)} | {
        n.id for n in every if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}


_CLI_TEXT = re.compile(r"-m tlm ([a-z][a-z-]*)")


class _Names:
    """The tlm modules that code uses, following the names it uses through its files.

    ``files`` are the files the names may lead into (the tests' own, or cli.py alone);
    ``handlers`` maps a subcommand to its modules, for the command lines found (none: not looked for).
    """

    def __init__(self, files: dict[Path, _File], root: Path, handlers: dict[str, set[str]] | None = None):
        self.files, self.root, self.handlers = files, root, handlers or {}
        self.by_module = {f.module: f for f in files.values()}
        self._cache: dict[tuple[Path, int], tuple[set[str], list]] = {}

    def fixture(self, f: _File, name: str) -> tuple[_File, list[ast.AST]] | None:
        """The fixture ``name`` a function of ``f`` asks for: in ``f``, else in a conftest.py above it."""
        folder = f.path.parent
        candidates = [f]
        while folder == self.root or self.root in folder.parents:
            conftest = self.files.get(folder / "conftest.py")
            if conftest is not None:
                candidates.append(conftest)
            folder = folder.parent
        for c in candidates:
            found = [d for d in c.defs.get(name, ()) if _is_fixture(d)]
            if found:
                return c, found
        return None

    def of(self, f: _File, nodes: list[ast.AST]) -> set[str]:
        """The modules that ``nodes`` of ``f`` (and all they lead to) touch."""
        touched: set[str] = set()
        seen: set[tuple[Path, str]] = set()
        work = [(f, n) for n in nodes]
        while work:
            here, node = work.pop()
            modules, refs = self._facts(here, node)
            touched |= modules
            for there, key, defs in refs:
                if (there.path, key) not in seen:
                    seen.add((there.path, key))
                    work.extend((there, d) for d in defs)
        return touched

    def _facts(self, f: _File, node: ast.AST) -> tuple[set[str], list[tuple[_File, str, list[ast.AST]]]]:
        """What ``node`` touches itself, and the definitions (file, name, nodes) it leads to."""
        key = (f.path, id(node))
        if key not in self._cache:
            every = list(ast.walk(node))
            own = _locals(node, every)
            refs: list[tuple[_File, str, list[ast.AST]]] = []
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                for arg in [*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs]:
                    where = self.fixture(f, arg.arg)
                    if where is not None:
                        refs.append((where[0], f"fixture {arg.arg}", where[1]))
            docs = {id(s.value) for s in every if isinstance(s, ast.Expr)}
            modules: set[str] = set()
            for sub in every:
                modules |= self._node(f, sub, own, docs, refs)
            self._cache[key] = (modules, refs)
        return self._cache[key]

    def _follow(self, f: _File, name: str, refs: list) -> None:
        if name in f.defs:
            refs.append((f, name, f.defs[name]))

    def _node(self, f: _File, n: ast.AST, own: set[str], docs: set[int], refs: list) -> set[str]:
        out: set[str] = set()
        if isinstance(n, ast.Name) and n.id not in own:
            if n.id in f.tlm_names:
                out |= f.tlm_names[n.id]
            elif n.id in f.tlm_modules:
                out.add(f.tlm_modules[n.id])
            elif n.id in f.test_names:
                target, attr = f.test_names[n.id]
                if attr is not None and target in self.by_module:
                    self._follow(self.by_module[target], attr, refs)
            else:
                self._follow(f, n.id, refs)
        elif isinstance(n, ast.Attribute):
            chain, root = [], n
            while isinstance(root, ast.Attribute):
                chain.append(root.attr)
                root = root.value
            chain.reverse()
            if isinstance(root, ast.Name) and root.id not in own and root.id in f.tlm_modules:
                module = f.tlm_modules[root.id]  # ``traverse.build_accel``, ``tlm.experiments.run.render``
                for attr in chain:
                    if not _is_module(f"{module}.{attr}"):
                        out |= _defining(module, attr)
                        break
                    module = f"{module}.{attr}"
                out.add(module)
            elif isinstance(root, ast.Name) and root.id not in own and root.id in f.test_names:
                target, attr = f.test_names[root.id]  # ``scenes.helper`` after ``from tests import scenes``
                other = self.by_module.get(target if attr is None else f"{target}.{attr}")
                if other is not None:
                    self._follow(other, chain[0], refs)
        elif isinstance(n, ast.ImportFrom):  # an import inside a followed function
            target = _resolve(f.module, n, f.path)
            if target.split(".")[0] == "tlm":
                for a in n.names:
                    out |= _defining(target, a.name)
        elif isinstance(n, ast.Import):
            out |= {a.name for a in n.names if a.name.split(".")[0] == "tlm"}
        if self.handlers and id(n) not in docs:
            out |= self._cli(f, n)
        return out

    def _cli(self, f: _File, n: ast.AST) -> set[str]:
        """A command line spelled in the source: ``main(["sub", ...])``, ``[python, "-m", "tlm", "sub"]``,
        ``f"... -m tlm sub ..."``: tlm.cli, the handler's modules (and tlm.__main__ for ``-m``)."""
        sub, main = None, False
        if isinstance(n, ast.Call) and n.args and isinstance(n.args[0], ast.List | ast.Tuple) and (
                (isinstance(n.func, ast.Name) and n.func.id in f.cli_main)
                or (isinstance(n.func, ast.Attribute) and n.func.attr == "main" and isinstance(n.func.value, ast.Name)
                    and f.tlm_modules.get(n.func.value.id) == "tlm.cli")):
            first = n.args[0].elts[:1]
            sub = first[0].value if first and isinstance(first[0], ast.Constant) else None
        elif isinstance(n, ast.List | ast.Tuple):
            words = [e.value if isinstance(e, ast.Constant) else None for e in n.elts]
            for i in range(len(words) - 2):
                if words[i] == "-m" and words[i + 1] == "tlm":
                    sub, main = words[i + 2], True
        elif isinstance(n, ast.Constant) and isinstance(n.value, str):
            m = _CLI_TEXT.search(n.value)
            if m:
                sub, main = m.group(1), True
        if not isinstance(sub, str) or sub not in self.handlers:
            return set()
        return {"tlm.cli", *self.handlers[sub], *(("tlm.__main__",) if main else ())}


@functools.cache
def cli_handlers(path: Path = PACKAGE / "cli.py") -> dict[str, set[str]]:
    """Subcommand -> the tlm modules its handler uses itself or in the helpers of cli.py it calls.

    Read from cli.py: ``x = sub.add_parser("name")`` then ``x.set_defaults(func=handler)``.
    """
    f = _read(path, "tlm.cli")
    tree = ast.parse(path.read_text())
    parser_of: dict[str, str] = {}
    handler_of: dict[str, str] = {}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                and isinstance(node.value, ast.Call) and isinstance(node.value.func, ast.Attribute)
                and node.value.func.attr == "add_parser" and node.value.args
                and isinstance(node.value.args[0], ast.Constant)):
            parser_of[node.targets[0].id] = node.value.args[0].value
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "set_defaults"
                and isinstance(node.func.value, ast.Name)):
            for kw in node.keywords:
                if kw.arg == "func" and isinstance(kw.value, ast.Name):
                    handler_of[node.func.value.id] = kw.value.id
    names = _Names({path: f}, path.parent)
    return {parser_of[var]: names.of(f, f.defs.get(func, [])) - {"tlm.cli"}
            for var, func in handler_of.items() if var in parser_of}


def _test_files(tests: Path) -> dict[Path, _File]:
    return {p: _read(p, _module_name(p, tests, "tests")) for p in sorted(tests.resolve().rglob("*.py"))}


def touches(path: Path, qualname: str, tests: Path = TESTS, names: _Names | None = None) -> set[str]:
    """The modules the test function ``qualname`` (``test_x`` or ``TestY.test_x``) of ``path`` touches."""
    tests = tests.resolve()
    names = names or _Names(_test_files(tests), tests, cli_handlers())
    f = names.files[path.resolve()]
    top, *rest = qualname.split(".")
    scopes = f.defs.get(top, [])[:1]
    for part in rest:  # a method of a test class: the class (its marks, its fixtures) and the method
        method = [n for n in getattr(scopes[-1], "body", []) if getattr(n, "name", None) == part]
        scopes += method[:1]
    assert len(scopes) == 1 + len(rest) and isinstance(scopes[-1], ast.FunctionDef | ast.AsyncFunctionDef), (
        f"{path.name}::{qualname} not found")
    nodes = [scopes[-1]] + [d for s in scopes[:-1] for d in s.decorator_list]
    return names.of(f, nodes)


def with_packages(modules: set[str]) -> set[str]:
    """``modules`` and every package above them (importing ``tlm.a.b`` runs ``tlm/a/__init__.py``)."""
    out = set(modules)
    for m in modules:
        parts = m.split(".")
        out |= {".".join(parts[:i]) for i in range(1, len(parts))}
    return out


@functools.cache
def package_imports(root: Path = PACKAGE) -> dict[str, set[str]]:
    """Module -> the tlm modules its source imports, anywhere in it (at the top or inside a function)."""
    out: dict[str, set[str]] = {}
    for path in sorted(root.rglob("*.py")):
        me = _module_name(path, root, "tlm")
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found |= {a.name for a in node.names if a.name.split(".")[0] == "tlm"}
            elif isinstance(node, ast.ImportFrom):
                target = _resolve(me, node, path)
                if target.split(".")[0] == "tlm":
                    found |= {target, *(f"{target}.{a.name}" for a in node.names if _is_module(f"{target}.{a.name}"))}
        out[me] = with_packages(found) - {me}
    return out


def untouched(fast: dict[Path, set[str]], tests: Path = TESTS) -> tuple[list[str], dict[str, list[str]]]:
    """The modules of tlm that no test of ``fast`` (file -> test names) touches, and for
    each of the others the tests that do.

    A private module (``_jit``: no interface of its own, the compiled inside of its
    package's modules) counts as touched when a touched module of its own package imports it.
    """
    tests = tests.resolve()
    names = _Names(_test_files(tests), tests, cli_handlers())
    by: dict[str, list[str]] = defaultdict(list)
    for path, functions in fast.items():
        for name in sorted(functions):
            for m in with_packages(touches(path, name, tests, names)):
                by[m].append(f"{path.resolve().relative_to(tests.parent)}::{name}")
    graph = package_imports()
    for m in tlm_modules():
        package, _, leaf = m.rpartition(".")
        if leaf.startswith("_") and not leaf.startswith("__") and m not in by:
            inside = [o for o in by if o.rpartition(".")[0] == package or o == package]
            by[m] = [f"through {o}" for o in sorted(inside) if m in graph.get(o, ())]
            if not by[m]:
                del by[m]
    return [m for m in tlm_modules() if m not in by], dict(by)


def test_the_fast_tier_touches_every_module(request):
    """Every module of tlm has a test in ``pytest -m "not slow"`` that uses it itself."""
    fast = fast_tests(request.session)
    assert len(fast) > 10, fast
    missing, _ = untouched(fast)
    assert not missing, ("modules no test of the fast tier uses (mark fewer of their tests slow, or split one "
                         f"into a fast and a slow part, or write one): {missing}")


TEST_A = '''
import pytest

from tlm import storage
from tlm.cli import main
from tlm.errors import InputError
from tests.helpers import fingerprint


@pytest.fixture
def err():
    return InputError("x")


def test_fast(err, registry):
    assert fingerprint() and err and registry


def test_cli():
    assert main(["params"]) == 0


def test_slow():
    assert storage.cache_root("x")


def test_shadow():
    """Like ``python -m tlm run``."""
    storage = 1
    assert storage.real
'''


def test_the_check_sees_a_module_lose_its_fast_test(tmp_path):
    """The analysis above can fail: a test that leaves the tier takes its modules with it, an
    import only a slow test uses touches nothing, and a command line touches its handler's
    modules; a name a test rebinds itself, or a docstring that spells a command, touches nothing."""
    tests = tmp_path / "tests"
    tests.mkdir()
    (tests / "__init__.py").write_text("")
    (tests / "helpers.py").write_text("from tlm.fingerprint import code_fingerprint\n\n\n"
                                      "def fingerprint():\n    return code_fingerprint()\n")
    (tests / "conftest.py").write_text("import pytest\n\nfrom tlm.registry import Registry\n\n\n"
                                       "@pytest.fixture\ndef registry():\n    return Registry\n")
    (tests / "test_a.py").write_text(TEST_A)
    path = tests / "test_a.py"
    fast = touches(path, "test_fast", tests)
    assert {"tlm.errors", "tlm.fingerprint", "tlm.registry"} <= fast and "tlm.storage" not in fast
    assert touches(path, "test_slow", tests) == {"tlm.storage"}
    assert touches(path, "test_shadow", tests) == set()
    handlers = cli_handlers()
    assert handlers["params"] and {"tlm.cli", *handlers["params"]} == touches(path, "test_cli", tests)
    missing, by = untouched({path: {"test_fast", "test_cli"}}, tests)
    assert "tlm.storage" in missing and "tlm.errors" not in missing and "tlm" in by
    missing, _ = untouched({path: {"test_cli", "test_slow"}}, tests)
    assert {"tlm.errors", "tlm.fingerprint"} <= set(missing) and "tlm.storage" not in missing


def test_every_subcommand_has_a_handler_the_check_reads():
    """cli.py read as the check reads it: each subcommand its handler, each handler tlm modules."""
    handlers = cli_handlers()
    assert {"run", "sweep", "scene", "params", "report"} <= set(handlers), sorted(handlers)
    assert all(h and all(m.split(".")[0] == "tlm" for m in h) for h in handlers.values()), handlers
