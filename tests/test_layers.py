"""The package's layers import one way, and no modules import each other in a circle.

Layers, bottom to top (docs/architecture.md, "Layers"): the base (errors, the config
schema, storage, the code fingerprint, the registries, host progress) -> scenes ->
kernels (with the memory/cache address streams) -> render -> oracle -> arch (the timing
model) -> experiments -> report -> the API and the cli (and the package's ``__init__``, which
re-exports the API). A module may import its own layer and those below it,
never one above, whether at the top of the file or inside a function; and the import
graph of tlm's modules has no cycle. Like a build farm's dependency check, this reads
the source (every ``import`` statement, ``ast``) rather than what happened to be imported.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "tlm"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("tlm.errors", "tlm.config", "tlm.builtin", "tlm.storage", "tlm.storage_json", "tlm.storage_lock",
     "tlm.storage_errors",  # (h252: what a failed write says, out of tlm.storage)
     "tlm.storage_files",  # (several files written all or none, out of tlm.storage)
     "tlm.storage_live", "tlm.storage_swap",  # (h334: a process's writers, the swap of a folder: out of tlm.storage)
     "tlm.storage_carry",  # (h456: what a rerun keeps of the user's files in an output's folder, out of tlm.storage)
     "tlm.fingerprint", "tlm.registry", "tlm.progress", "tlm.whole_imports", "tlm.caches", "tlm.config_words",
     "tlm.mesh_files", "tlm.claims", "tlm.cache_admin",
     "tlm.cache_look",  # (h517: a look at an entry that is no use, what an entry is: out of tlm.cache_admin)
     "tlm.config_paths", "tlm.config_read",
     "tlm.config_sections"),
    ("tlm.scenes",),
    ("tlm.kernels",
     "tlm.kernels.threads_forked"),  # (h480: the forked process pool, out of tlm.kernels.threads)
    ("tlm.render",),
    ("tlm.oracle",),
    ("tlm.arch",),
    ("tlm.experiments",
     "tlm.experiments.reference_resume",  # (h454: an interrupted reference resumed, out of reference)
     "tlm.experiments.error_cost_blur",  # (h483: error-vs-cost's blur warning, once per study, out of error_cost)
     "tlm.experiments.frame_keys",  # (h487: the scene's part of a frame's key, remembered, out of frames)
     "tlm.experiments.sweep_folder",  # (h489: what a sweep finds in its folder from before it, out of sweep)
     "tlm.experiments.photon_warnings",  # (h505: the line on paths cut with power in flight, out of run_warnings)
     "tlm.experiments.calibrate_fit"),  # (h539: how well tlm calibrate's fit is determined, out of thesis)
    ("tlm.report",
     "tlm.report.written",  # (h477: which files of a run folder its run wrote, the report's only reads)
     "tlm.report.summary_studies",  # (h487: the summary's words on the studies, no figure, out of summary)
     "tlm.report.tradeoff_studies",  # (h487: what the tradeoff section reads of a study, no figure, out of tradeoff)
     "tlm.report.study_tables",  # (h501: a study folder's tables read and checked, out of collect)
     "tlm.report.compare",  # (h530: runs of one scene-mode compared, B/A, and what differs, out of summary)
     "tlm.report.numbers"),  # (h545: how the report writes a number, one rule for its tables, figures and text)
    # tlm: the package's __init__, which re-exports tlm.api
    ("tlm.api", "tlm.api_studies", "tlm.api_scenes", "tlm.api_cache", "tlm.api_common",
     "tlm.api_config",  # (h311: Config, load_config and scene_file, out of tlm.api)
     "tlm.cli", "tlm.cli_args",
     "tlm.cli_report", "tlm.cli_run", "tlm.cli_signals", "tlm.cli_failed", "tlm.cli_streams", "tlm.cli_cache",
     "tlm.cli_tables",
     "tlm.cli_parser",  # (h487: the commands' arguments, their help and checks, out of tlm.cli)
     "tlm.__main__", "tlm"),
)


def layer_of(module: str) -> int:
    """The layer of ``module``: that of the longest prefix named in :data:`LAYERS`."""
    best, depth = None, -1
    for i, names in enumerate(LAYERS):
        for name in names:
            inside = module == name or (name != "tlm" and module.startswith(name + "."))  # tlm: its __init__
            if inside and name.count(".") > depth:
                best, depth = i, name.count(".")
    if best is None:
        raise AssertionError(f"{module} is in no layer: add it to LAYERS and to docs/architecture.md")
    return best


def module_name(path: Path, root: Path = PACKAGE) -> str:
    parts = ("tlm", *path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, root: Path = PACKAGE) -> list[tuple[str, int]]:
    """``(imported tlm module, line)`` of every import statement in ``path``, anywhere in it."""
    me = module_name(path, root)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.extend((a.name, node.lineno) for a in node.names if a.name.split(".")[0] == "tlm")
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join([*base, *([node.module] if node.module else [])])
            else:
                target = node.module or ""
            if target.split(".")[0] != "tlm":
                continue
            subs = [f"{target}.{a.name}" for a in node.names if _is_module(f"{target}.{a.name}", root)]
            out.extend((s, node.lineno) for s in subs)
            if len(subs) < len(node.names):
                out.append((target, node.lineno))
    return out


def _is_module(name: str, root: Path) -> bool:
    rel = Path(*name.split(".")[1:])
    return (root / rel).with_suffix(".py").is_file() or (root / rel / "__init__.py").is_file()


def graph(root: Path = PACKAGE) -> dict[str, list[tuple[str, int]]]:
    return {module_name(p, root): imports(p, root) for p in sorted(root.rglob("*.py"))}


def upward(root: Path = PACKAGE) -> list[str]:
    """Every import of a module from a higher layer, as ``'a (line n) -> b'``."""
    bad = []
    for mod, targets in graph(root).items():
        for target, line in targets:
            if layer_of(target) > layer_of(mod):
                bad.append(f"{mod} (line {line}) -> {target}")
    return bad


def cycles(root: Path = PACKAGE) -> list[list[str]]:
    """The import graph's strongly connected components of more than one module (Tarjan)."""
    g = {m: sorted({t for t, _ in ts if t != m}) for m, ts in graph(root).items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
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
                found.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return found


@pytest.mark.slow
def test_every_module_is_in_a_layer():
    for mod in graph():
        layer_of(mod)


@pytest.mark.slow
def test_no_module_imports_from_a_layer_above_it():
    assert upward() == []


@pytest.mark.slow
def test_the_import_graph_has_no_cycle():
    assert cycles() == []


def _write(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = root / "tlm" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root / "tlm"


def test_the_check_finds_an_upward_import_even_inside_a_function(tmp_path):
    root = _write(tmp_path, {"__init__.py": "", "kernels/__init__.py": "", "arch/__init__.py": "",
                             "arch/model.py": "X = 1\n",
                             "kernels/shade.py": "def f():\n    from tlm.arch.model import X\n    return X\n"})
    assert upward(root) == ["tlm.kernels.shade (line 2) -> tlm.arch.model"]


def test_the_check_finds_a_cycle_within_a_layer(tmp_path):
    root = _write(tmp_path, {"__init__.py": "", "report/__init__.py": "",
                             "report/a.py": "from tlm.report import b\n", "report/b.py": "from . import a\n"})
    assert upward(root) == []
    assert cycles(root) == [["tlm.report.a", "tlm.report.b"]]


def test_a_module_outside_the_layers_is_named():
    with pytest.raises(AssertionError, match=r"tlm\.plugins is in no layer"):
        layer_of("tlm.plugins")
