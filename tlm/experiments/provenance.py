"""Where a result came from: the versions of tlm and its libraries, which kernels ran (the
compiled numba ones or the numpy ones, ``TLM_KERNELS``), tlm's git revision (and whether the
checkout was modified from it) and the fingerprint of tlm's code.

``results.json`` of a run, every sweep point's row and a study's ``provenance.json``
record them, so that a number can be traced to the code that produced it.
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import hashlib
import os
import platform
import subprocess
from pathlib import Path

# whose versions are recorded: tlm and the libraries that compute, compile or draw its results
PACKAGES = ("tlm", "numpy", "scipy", "numba", "simpy", "trimesh", "pyyaml", "pillow", "matplotlib")


def versions() -> dict[str, str]:
    """Python's, the platform's and :data:`PACKAGES`' versions ("not installed" for one missing),
    and ``kernels``: the engine of the kernels that run here, ``numba`` (compiled) or ``numpy``
    (:func:`kernels_here`: :func:`tlm.kernels.engine.engine`'s answer, from ``TLM_KERNELS``; an
    unknown value is refused as bad input). The images do not depend on it; host seconds do.
    The versions are the packages' metadata (tlm's: the code that runs, :func:`tlm_version`): nothing
    is imported for them."""
    import importlib.metadata as md

    out = {"python": platform.python_version(), "platform": platform.platform()}
    for pkg in PACKAGES:
        try:
            out[pkg] = tlm_version() if pkg == "tlm" else md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    out["kernels"] = kernels_here()
    return out


@functools.cache
def tlm_version() -> str:
    """The version of the tlm whose code runs (this package), not of whichever copy is installed:
    in a source tree (this package is the ``tlm/`` beside a ``pyproject.toml`` of project ``tlm``:
    a checkout run with ``python -m tlm``, installed in editable mode or not) that file's
    ``version``; else the installed distribution's where its ``tlm/__init__.py`` is this package's
    (or it is an editable install of this source tree: its ``direct_url.json``, PEP 610);
    else ``unknown`` (with the installed copy's version where there is one: ``unknown (installed
    tlm 0.1.0 is another copy)``). Read once a process: the code that runs is the one imported."""
    import importlib.metadata as md

    here = Path(__file__).resolve().parents[1]  # (this package's folder)
    own = _source_version(here.parent / "pyproject.toml")
    if own is not None:
        return own
    try:
        dist = md.distribution("tlm")
        installed = dist.version
        init = Path(os.fspath(dist.locate_file("tlm/__init__.py")))
        if (init.is_file() and init.resolve() == here / "__init__.py") or _editable_of(dist, here.parent):
            return installed
    except md.PackageNotFoundError:
        return "unknown (not installed)"
    except (OSError, ValueError):  # (metadata unreadable)
        return "unknown"
    return f"unknown (installed tlm {installed} is another copy)"


def _editable_of(dist, folder: Path) -> bool:
    """Whether the distribution ``dist`` is an editable install of the source tree ``folder`` (its
    ``direct_url.json``: ``dir_info.editable`` and a ``file:`` url of that folder); False where it
    says otherwise or cannot be read."""
    import json
    from urllib.parse import urlsplit
    from urllib.request import url2pathname

    try:
        direct = json.loads(dist.read_text("direct_url.json") or "null")
        url = urlsplit(direct["url"])
        if not direct.get("dir_info", {}).get("editable") or url.scheme != "file":
            return False
        return Path(url2pathname(url.path)).resolve() == folder
    except (OSError, ValueError, TypeError, KeyError, AttributeError):  # (no such file, or not PEP 610's)
        return False


def _source_version(pyproject: Path) -> str | None:
    """``project.version`` of the ``pyproject.toml`` at ``pyproject`` where its ``project.name`` is
    tlm; None where there is no such file, it is not tlm's, or it gives no version as a string."""
    import tomllib

    try:
        project = tomllib.loads(pyproject.read_text(encoding="utf-8")).get("project")
    except (OSError, ValueError, UnicodeDecodeError):  # (none there; tomllib.TOMLDecodeError is a ValueError)
        return None
    if not isinstance(project, dict) or project.get("name") != "tlm":
        return None
    version = project.get("version")
    return version if isinstance(version, str) and version else None


def kernels_here() -> str:
    """:func:`tlm.kernels.engine.engine` (``numba`` where numba imports, unless ``TLM_KERNELS=numpy``),
    without importing numba where it is sure to import (:func:`_numba_sound`): a process that runs
    no kernel (a sweep whose frames are all cached) records the engine its kernels would run and
    spends no 0.2 - 0.5 s importing numba for it. Where numba was imported or tried already in this
    process, or a kernel asked for the engine, that answer; where the check is not sure (numba
    missing, another module named numba found first, a dependency out of numba's range, a file of its
    wheel missing or no wheel's record of its files: a source tree's), numba's
    import decides, as the kernels' own :func:`~tlm.kernels.engine.engine` does."""
    import sys

    from tlm.kernels.engine import engine, numba_available

    name = os.environ.get("TLM_KERNELS", "").strip().lower()
    tried = getattr(numba_available, "cache_info", None)  # (its answer remembered: numba's import tried)
    if name not in ("", "numba") or "numba" in sys.modules or tried is None or tried().currsize:
        return engine()  # (numpy, a bad value refused, or numba's import tried: engine()'s answer at no cost)
    return "numba" if _numba_sound() else engine()


@functools.cache
def _numba_sound() -> bool:
    """Whether ``import numba`` is sure to succeed, told without importing it: the module that import
    would find is the installed distribution's own ``numba/__init__.py`` (no other module named numba
    earlier on the path, which the import would run instead), llvmlite's likewise, and Python, NumPy
    and llvmlite are within the ranges numba's metadata requires (the checks numba's own first lines
    make, ``numba._ensure_critical_deps``), each one's files whole (:func:`_files_whole`). False where
    any of that is not so or cannot be told: then the import itself decides (:func:`kernels_here`)."""
    import importlib.metadata as md
    import importlib.util

    try:
        from packaging.requirements import Requirement
        from packaging.specifiers import SpecifierSet

        dist = md.distribution("numba")
        for mod in ("numba", "llvmlite"):
            spec = importlib.util.find_spec(mod)
            own = md.distribution(mod)
            init = own.locate_file(f"{mod}/__init__.py")
            if spec is None or spec.origin is None or os.path.realpath(spec.origin) != os.path.realpath(init):
                return False
            if not _files_whole(own, mod):  # (a compiled extension deleted: the import fails)
                return False
        python = dist.metadata.get("Requires-Python")
        if python and not SpecifierSet(python).contains(platform.python_version(), prereleases=True):
            return False
        for req in map(Requirement, dist.requires or ()):
            if req.marker is not None and not req.marker.evaluate({"extra": ""}):
                continue  # (an extra's or another platform's requirement)
            if not req.specifier.contains(md.version(req.name), prereleases=True):
                return False
        import numpy  # (imported by tlm already: the one numba would check, against its metadata's)

        return numpy.__version__ == md.version("numpy")
    except Exception:  # (metadata missing or unreadable, packaging absent: not sure)
        return False


def _files_whole(dist, mod: str) -> bool:
    """Whether every file of package ``mod`` that ``dist``'s ``RECORD`` lists with a size is there, with that
    size: numba's compiled extensions and llvmlite's shared library among them (one deleted or cut short:
    the import fails, and the numpy kernels run). False without a ``RECORD`` (a source tree's ``egg-info``,
    whose extensions may not be built; an installer that writes none): not sure. A library that is there
    but does not load (a system library it needs missing) is not told."""
    import csv

    base = os.fspath(dist.locate_file(""))
    listed = 0
    try:
        for row in csv.reader((dist.read_text("RECORD") or "").splitlines()):
            if len(row) >= 3 and row[0].startswith(f"{mod}/") and row[2]:
                if os.stat(os.path.join(base, row[0])).st_size != int(row[2]):
                    return False
                listed += 1
    except (OSError, ValueError, csv.Error):  # (a file missing; a size that is not a number)
        return False
    return listed > 0


def _git(*args: str, cwd: Path) -> str | None:
    """``git args`` in ``cwd``: its output, stripped; None where git fails or is missing. Its bytes are read as a
    file name is (``os.fsdecode``), whatever the locale's encoding: a checkout in a folder of a non-ASCII name
    (``--show-toplevel``) under ``LC_ALL=C`` is that folder, as ``Path(__file__)`` names it, not a decoding error."""
    try:
        out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return os.fsdecode(out.stdout).strip() if out.returncode == 0 else None


def _checkout() -> Path | None:
    """The git checkout tlm runs from, where tlm's package is that checkout's ``tlm/``; None
    for an installed copy (a site-packages inside another git project must not lend tlm its
    project's commit)."""
    here = Path(__file__).resolve().parents[1]
    top = _git("rev-parse", "--show-toplevel", cwd=here)
    if top is None or (Path(top).resolve() / "tlm") != here:
        return None
    return Path(top)


def git_revision() -> str | None:
    """The commit of tlm's checkout (None outside tlm's own git checkout, or without git)."""
    top = _checkout()
    return None if top is None else (_git("rev-parse", "HEAD", cwd=top) or None)


def code_state() -> dict:
    """What code a result came from: ``git_revision`` (:func:`git_revision`),
    ``git_modified`` (whether tracked files of the checkout differ from that commit: the
    result is then not the commit's; None outside a checkout) and ``code_fingerprint``
    (:func:`tlm.fingerprint.code_fingerprint`, the package's content: the same for the
    same code, in a checkout or installed, edited or not)."""
    from tlm.fingerprint import code_fingerprint

    top = _checkout()
    rev = None if top is None else (_git("rev-parse", "HEAD", cwd=top) or None)
    status = None if rev is None else _git("status", "--porcelain", "--untracked-files=no", cwd=top)
    return {"git_revision": rev, "git_modified": None if status is None else bool(status),
            "code_fingerprint": code_fingerprint()}


def version_line() -> str:
    """``tlm --version``'s line, what identifies the code that runs, as ``results.json`` records it
    (:func:`code_state`): ``tlm 0.1.0 (Python 3.11.7; git <commit>[, modified]; code <code_fingerprint>)``;
    ``no git checkout`` in place of the commit for an installed copy (its fingerprint, the same for the
    same code, says which). Nothing heavy imported."""
    state = code_state()
    rev = state["git_revision"]
    git = "no git checkout" if rev is None else f"git {rev}{', modified' if state['git_modified'] else ''}"
    return f"tlm {tlm_version()} (Python {platform.python_version()}; {git}; code {state['code_fingerprint']})"


def provenance(study: str | None, host_seconds: float | None) -> dict:
    """What a study folder records of where it came from (``provenance.json``)."""
    return {"study": study, "versions": versions(), **code_state(),
            "host_seconds": None if host_seconds is None else round(host_seconds, 3)}


# the identities computed inside identities_remembered(), by scene file (None: outside, none kept)
_REMEMBERED: contextvars.ContextVar[dict | None] = contextvars.ContextVar("tlm_scene_identities", default=None)


@contextlib.contextmanager
def identities_remembered():
    """Inside, :func:`scene_identity` computes the identity of a scene file once and gives it
    again to every later call for the same file, as long as the file keeps its modification
    time and size (keyed by the path as given, the path resolved, and those two). A report
    (:func:`tlm.report.build_report`) or a thesis study judges every cell of a scene by its
    file (:func:`tlm.experiments.thesis.table_of`) and the built-in files beside it: each is
    digested, its YAML parsed and its meshes read, once rather than once a cell. The mesh files
    are not watched: the scope is meant for one piece of work that does not change them (a
    change to a mesh inside is seen after it). A scope inside another shares the outer's
    identities; another thread keeps none unless it opens its own scope."""
    if _REMEMBERED.get() is not None:
        yield
        return
    token = _REMEMBERED.set({})
    try:
        yield
    finally:
        _REMEMBERED.reset(token)


def scene_identity(source, reads: list | None = None) -> str:
    """The scene file ``source`` (a run's ``scene.source``) as a digest of its bytes and of
    those of the files its ``extends:`` chain names (found as the loader finds them, a built-in
    name's file among them: :func:`_extended`), and of the files its geometry's meshes are read from (each
    mesh file, an OBJ's MTL libraries, a glTF's buffers: :func:`tlm.scenes.meshes.mesh_files`,
    by their content and, for the libraries and buffers, their names beside the mesh): two
    copies of one scene file with copies of its meshes, in the same places relative to it, are
    one scene, wherever they are; the same scene file beside other mesh contents is another.
    A scene without mesh files keeps the digest of its scene files alone. A file that is not
    on this machine (a folder written elsewhere) is told by its path. Eq. 5.2's groups
    (:mod:`tlm.experiments.scaling`) and the thesis's scenes
    (:func:`tlm.experiments.thesis.table_of`) are told apart so.

    ``reads``: what a load of that scene noted (:func:`tlm.config.noting_reads`, as :func:`tlm.experiments.run.render`
    loads it): each mesh file's digest and what names its other files are taken from its ``("mesh", ...)`` record,
    and the digests of those files (MTL libraries, glTF buffers) from its ``("side", ...)`` records, not read and
    parsed again (a 27 MB OBJ: its sha256 once, the load's; a glTF's JSON alone read, for its buffers' names:
    :func:`_files_noted`); the same identity as without them."""
    if not source:
        return "(no scene file recorded)"
    path = Path(str(source))
    memo = _REMEMBERED.get()
    if memo is None or reads:
        return _scene_identity(path, reads)
    try:
        st = path.stat()
        key = (str(path), str(path.resolve()), st.st_mtime_ns, st.st_size)
    except OSError:  # (not on this machine: told by its path, at no cost)
        return _scene_identity(path)
    if key not in memo:
        memo[key] = _scene_identity(path)
    return memo[key]


def _scene_identity(path: Path, reads: list | None = None) -> str:
    """:func:`scene_identity` of the scene file ``path``, computed (``reads``: a load's, :func:`_noted`)."""
    ident = _identity(path, 0)
    meshes = [] if not ident.startswith("sha256 ") else _mesh_lines(path, reads) if reads else _mesh_lines(path)
    if not meshes:
        return ident
    digest = hashlib.sha256(ident.encode())
    for line in meshes:
        digest.update(f"{line}\n".encode())
    return f"sha256 {digest.hexdigest()[:16]}"


def _mesh_lines(path: Path, reads: list | None = None) -> list[str]:
    """A line per mesh file of the scene file ``path``'s geometry, in its order: the digests of
    the files a load of it reads (:func:`tlm.scenes.meshes.mesh_files`: the mesh's content, the
    others' with their paths relative to the mesh; from ``reads`` where a load noted them, :func:`_noted`),
    or that it is missing or unreadable."""
    from tlm.errors import InputError
    from tlm.scenes.meshes import mesh_files

    try:
        paths = mesh_paths(path)
    except (InputError, OSError, ValueError):
        return []  # (a scene file that does not load: its bytes tell it)
    noted, sides = _noted(reads), _sides(reads)
    out = []
    for i, mesh in enumerate(paths):
        try:
            files = _files_noted(mesh, noted.get(os.path.realpath(mesh)), sides) or mesh_files(mesh)
        except (InputError, OSError, ValueError) as e:
            out.append(f"mesh {i}: {'missing' if not mesh.is_file() else f'unreadable ({type(e).__name__})'}")
            continue
        parts = [f"{files[0][1]['sha256']} {files[0][1]['size']}"]
        parts += [f"{os.path.relpath(f, mesh.parent)} {d['sha256']} {d['size']}" for f, d in files[1:]]
        out.append(f"mesh {i}: " + "; ".join(parts))
    return out


def _noted(reads: list | None) -> dict[str, tuple]:
    """The ``("mesh", path, digest, names, resolve)`` records of a scene load's ``reads`` by the mesh's real
    path (:func:`tlm.scenes.cache.mesh`: the digest it computed of the file, what names its other files)."""
    return {os.path.realpath(r[1]): r for r in reads or () if r and r[0] == "mesh" and len(r) == 5 and r[2]}


def _sides(reads: list | None) -> dict[str, set[tuple[str, int | None]]]:
    """The ``("side", path, sha256 of the bytes read[, their size])`` records of a scene load's ``reads`` (an OBJ's
    MTL libraries, a glTF's buffers and images, :func:`tlm.scenes.objfile.read_bytes`,
    :func:`tlm.scenes.mesh_checks.noting_resolver`; a cached mesh's libraries, checked: :func:`tlm.scenes.cache.mesh`)
    by the file's real path: each file's digests, each with the size read where the record gives it (else None)."""
    out: dict[str, set[tuple[str, int | None]]] = {}
    for r in reads or ():
        if r and r[0] == "side" and len(r) in (3, 4) and isinstance(r[2], str):
            size = r[3] if len(r) == 4 and isinstance(r[3], int) and not isinstance(r[3], bool) else None
            out.setdefault(os.path.realpath(r[1]), set()).add((r[2], size))
    return out


def _files_noted(mesh: Path, record: tuple | None,
                 sides: dict[str, set[tuple[str, int | None]]]) -> list[tuple[Path, dict]] | None:
    """:func:`tlm.scenes.meshes.mesh_files` of ``mesh`` from a load's ``record`` of it (:func:`_noted`) and the files
    its parse read beside it (``sides``, :func:`_sides`): the mesh's digest the load computed, and the digest of each
    other file (an OBJ's libraries, from what the record names; a glTF's buffers, from its JSON: a ``.glb``'s JSON
    chunk alone) the sha256 of the bytes the load read, with their size (the record's, else the file's now); a file
    whose read was not noted (or that two reads found different) digested now. Without the mesh read again: the
    same list, the same digests. None where there is no record."""
    from tlm.caches import file_digest
    from tlm.scenes.meshes import mesh_format

    if record is None:
        return None
    _, _, digest, names, resolve = record
    mesh = Path(mesh)
    if isinstance(names, list):
        others = resolve(mesh, names) if names else []
    elif mesh_format(mesh)[0] in (".gltf", ".glb"):  # (its parse names none: any .gltf, a .glb with external buffers)
        others = _buffer_paths(mesh)
    else:
        return None

    def noted(p: Path) -> dict:
        got = sides.get(os.path.realpath(p), set())
        shas, sizes = {sha for sha, _ in got}, {n for _, n in got if n is not None}
        if len(shas) != 1 or len(sizes) > 1:
            return file_digest(p)
        # (the size read where the record gives it: a file saved between the load and now, to another size, is
        # not its old sha256 with its new size, a digest of neither; else the size now)
        return {"size": sizes.pop() if sizes else os.stat(p).st_size, "sha256": shas.pop()}

    return [(mesh, digest), *((Path(p), noted(Path(p))) for p in others)]


def _buffer_paths(path: Path) -> list[Path]:
    """The buffer files of the glTF ``path`` (its ``buffers`` by ``uri``, found as the load finds them, as
    :func:`tlm.scenes.meshes.mesh_files` names them); of a ``.glb`` its JSON chunk is read, not its binary one."""
    import json
    from urllib.parse import unquote

    from tlm.scenes.materials import gltf_json
    from tlm.scenes.meshes import mesh_format
    from tlm.scenes.objfile import read_bytes

    header, data = None, None
    with open(path, "rb") as f:
        head = f.read(20)
        if head[:4] == b"glTF" and len(head) == 20 and head[16:20] == b"JSON":  # (a .glb: header, JSON chunk's)
            try:
                header = json.loads(f.read(int.from_bytes(head[12:16], "little")))
            except ValueError:
                header = None  # (read whole below: gltf_json says what is wrong)
        elif not mesh_format(path)[1]:  # (a .gltf, its JSON: read once; a compressed file is read whole below)
            data = head + f.read()
    if not isinstance(header, dict):
        header = gltf_json(path, read_bytes(path) if data is None else data)
    out = []
    for b in header.get("buffers") or []:
        uri = b.get("uri") if isinstance(b, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:"):
            file = path.parent / uri
            out.append(file if file.is_file() else path.parent / unquote(uri))  # (as the load finds it)
    return out


def mesh_paths(scene: Path) -> list[Path]:
    """The mesh files the geometry of the scene file ``scene`` names (its ``extends:`` chain
    merged, as the loader merges it: a mesh path is relative to the file that names it), in
    the geometry's order, found as the loader finds them (whether they are there or not). An
    :class:`~tlm.errors.InputError` where the scene file cannot be read."""
    from tlm.scenes.compose import mesh_path
    from tlm.scenes.loader import read_scene_tree

    raw, geom_path = read_scene_tree(Path(scene), ())
    geometry = raw.get("geometry")
    items = [geometry] if isinstance(geometry, dict) else geometry if isinstance(geometry, list) else []
    return [mesh_path(i["mesh"], geom_path) for i in items
            if isinstance(i, dict) and isinstance(i.get("mesh"), str) and i["mesh"]]


def _identity(path: Path, depth: int) -> str:
    import yaml

    try:
        data = path.read_bytes()
    except OSError:
        return f"path {path}"
    digest = hashlib.sha256(data)
    try:
        ref = (yaml.safe_load(data) or {}).get("extends")
    except (ValueError, AttributeError, yaml.YAMLError):
        ref = None
    base = _extended(path, ref) if isinstance(ref, str) and ref and depth < 8 else None
    if base is not None:
        digest.update(_identity(base, depth + 1).encode())
    return f"sha256 {digest.hexdigest()[:16]}"


def _extended(path: Path, ref: str) -> Path | None:
    """The scene file that ``extends: ref`` in the scene file ``path`` names, found as the loader finds it
    (:func:`tlm.scenes.loader.resolve_scene_path`: beside it, then the working folder, then the built-in scenes, a
    built-in name among them: an edit to the built-in ``cornell.yaml`` changes the identity of a file that extends
    it); where none is found, a path beside it (told by its path), or None for a name."""
    from tlm.errors import InputError
    from tlm.scenes.loader import resolve_scene_path

    try:
        return resolve_scene_path(ref, path.parent, str(path), key="extends")
    except (InputError, OSError, ValueError):
        return path.parent / ref if ref.endswith(".yaml") or "/" in ref else None


def scene_label(source) -> str:
    """A scene file as a user names it: a built-in one by its name (``thesis/ring``), any
    other by its path."""
    from tlm.scenes.loader import scenes_dir

    try:
        return Path(str(source)).resolve().relative_to(scenes_dir().resolve()).with_suffix("").as_posix()
    except (ValueError, OSError):
        return str(source)
