"""How the report names a scene, and shows a path a run recorded, so that one name means
one scene file throughout (:func:`scene_label`, :func:`name_scenes`) and no path of the
machine that ran a study is shown as it was there (:func:`shown_paths`); and how it writes a
sweep factor's value: as its YAML does (``null``, not ``None``), a null with what it asks of
its key where the key's help says (``null (floor(ln n))``, :func:`value_text`).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import Any

from tlm.config import describe

SCENE_FOLDERS = ("scenes", "_scenes")  # the built-in scenes' folder in a checkout, and in the wheel


def _builtin_under(source: str, names: list[str] | None = None) -> str | None:
    """The built-in name of the scene file ``source`` (posix text): its path under this
    installation's scenes folder, or, for a file of another checkout (a run made elsewhere),
    under a ``scenes`` folder where that path is a built-in name here (``names``: the
    built-in names; None: that second test is not made). None: neither."""
    from tlm.scenes.loader import scenes_dir

    p = Path(source)
    if not p.is_absolute() or p.suffix.lower() not in (".yaml", ".yml"):
        return None
    try:
        return p.resolve().relative_to(scenes_dir().resolve()).with_suffix("").as_posix()
    except (ValueError, OSError):
        pass
    if names is None:
        return None
    parts = p.parts
    for i in range(len(parts) - 2, -1, -1):
        if parts[i] in SCENE_FOLDERS:
            tail = Path(*parts[i + 1:]).with_suffix("").as_posix()
            return tail if tail in names else None
    return None


def _same_builtin(source: str) -> str | None:
    """The built-in name of a scene file on this machine under a ``scenes`` folder whose
    built-in file of that name here is the same scene (:func:`~tlm.experiments.provenance.scene_identity`:
    the same bytes, the same ``extends:`` chain), else None."""
    from tlm.experiments.provenance import scene_identity
    from tlm.scenes.loader import list_scenes, scenes_dir

    tail = _builtin_under(source, list_scenes())
    if tail is None or not Path(source).is_file():
        return None
    mine = scenes_dir() / f"{tail}{Path(source).suffix}"
    return tail if mine.is_file() and scene_identity(source) == scene_identity(mine) else None


def scene_label(ref: Any, source: Any, name: Any = None) -> str:
    """A scene as the report names it, so that one name means one scene file throughout.

    ``ref``: the run config's ``scene`` (what the user wrote); ``source``: the scene file the
    run loaded (``results.json`` ``scene.source``); ``name``: the scene's ``name`` in its file.
    A built-in scene is named by its path under ``scenes/`` without ``.yaml`` (``room`` is
    ``scenes/room.yaml``, ``thesis/room`` is ``scenes/thesis/room.yaml``, though both files say
    ``name: room``), wherever the run was made: a path to a file of another checkout's
    ``scenes`` folder too, where that file is not on this machine (a run made elsewhere) or is
    the same scene as the built-in one here (:func:`_same_builtin`); another scene file by the
    path its config gave (relative to that config: a user's own, edited ``scenes/cornell.yaml``
    that a config names ``cornell.yaml`` is ``cornell.yaml``, not the built-in ``cornell``), or,
    without a config, by its file's path. The ``name`` alone only where neither is known."""
    src = str(source).replace("\\", "/") if source else ""
    if isinstance(ref, str) and ref.strip():
        r = ref.strip().replace("\\", "/")
        if not r.lower().endswith((".yaml", ".yml")) and not r.startswith("/") and src.endswith(f"/{r}.yaml"):
            return r  # a built-in name: the loader takes one without .yaml as built-in first
        builtin = _builtin_under(src) if src else None
        if builtin is not None:
            return builtin
        same = _same_builtin(src)  # (a path to a built-in file of another checkout: ../scenes/room.yaml)
        if same is not None:
            return same
        n = len(Path(r).parts)  # thesis/ring.yaml: the built-in file (the loader's last resort), of another checkout
        if (not r.startswith(("/", ".")) and src.endswith(f"/{r}") and len(Path(src).parts) > n
                and Path(src).parts[-n - 1] in SCENE_FOLDERS and not Path(src).is_file()):
            return r.rsplit(".", 1)[0]  # (a file on this machine is that only where its content is: a user's
        # own scenes/cornell.yaml, edited, is not the built-in cornell); a config's absolute path
        # (tlm.config.scene_from made it so) relative to the current folder where it lies under it
        return file_name(r) if Path(r).is_absolute() else r
    if src:
        from tlm.scenes.loader import list_scenes

        return _builtin_under(src, list_scenes()) or src
    return str(name) if name is not None else "(scene unknown)"


_ABSOLUTE_PATH = re.compile(r"(?<![\w.~/-])/[^\s:;,'\"()<>]*[^\s:;,'\"()<>.]")  # (not a sentence's full stop)


def _packaged(path: Path) -> str | None:
    """The file ``path`` (absolute) of this installation's built-in scenes or experiments (their mesh
    and material files too) by its place in the repository, ``scenes/meshes/CornellBox-Original.mtl``,
    ``configs/extreme.yaml``, in a checkout as in an installed copy (``site-packages/tlm/_scenes``,
    ``_configs``: :func:`tlm.scenes.loader.scenes_dir`, :func:`tlm.builtin.configs_dir`); else None."""
    from tlm.builtin import configs_dir
    from tlm.scenes.loader import scenes_dir

    for root, shown in ((scenes_dir(), "scenes"), (configs_dir(), "configs")):
        try:
            return f"{shown}/{path.resolve().relative_to(root.resolve()).as_posix()}".removesuffix("/.")
        except (ValueError, OSError):
            continue
    return None


def shown_path(path: str, folder: Path | None = None) -> str:
    """An absolute path a run recorded (on the machine it ran on, in a temporary checkout
    perhaps) as the report shows it: a built-in scene file by its place in the repository
    (``scenes/extreme/bad_scale_zero.yaml``; one of another checkout's ``scenes`` folder where it is not on
    this machine or is the same scene as the built-in one here, as :func:`scene_label` names it), and so any
    file of this installation's built-in scenes and experiments (``configs/extreme.yaml``, where an installed
    copy has ``.../site-packages/tlm/_configs/extreme.yaml``: :func:`_packaged`), a file in ``folder`` (the
    run's or study's folder) relative to it, one under the current folder relative to that; else as given."""
    from tlm.scenes.loader import list_scenes

    p = Path(path)
    builtin = _builtin_under(path)
    if builtin is None:  # (another checkout's built-in file: where it is on this machine, only the same scene as
        # the one here, as scene_label; a user's own, edited .../scenes/cornell.yaml is not scenes/cornell.yaml)
        tail = _builtin_under(path, list_scenes())
        builtin = _same_builtin(path) if tail is not None and p.is_file() else tail
    if builtin is not None:
        return f"scenes/{builtin}{p.suffix}"
    packaged = _packaged(p) if p.is_absolute() else None
    if packaged is not None:
        return packaged
    for base in ([Path(folder)] if folder is not None else []) + [Path.cwd()]:
        try:
            return p.relative_to(base.resolve()).as_posix() or "."
        except (ValueError, OSError):
            continue
    return path


def shown_paths(text: str, folder: Path | None = None) -> str:
    """``text`` (a recorded message) with each absolute path in it as :func:`shown_path` shows it."""
    return _ABSOLUTE_PATH.sub(lambda m: shown_path(m.group(0), folder), text)


def name_scenes(runs: list) -> None:
    """Fix each run's :attr:`Run.scene_label` so that one name stands for one scene file.

    Where two scene files that are not built-in would get one name (the same path written in
    two configs, relative to two folders), each is named by its file's path instead
    (:func:`file_name`). Where a built-in name stands for two scene files on this machine of
    different content (:func:`~tlm.experiments.provenance.scene_identity`: the built-in ``cornell``
    of this installation, and that of another checkout with an edited ``scenes/cornell.yaml``),
    the file that is this installation's built-in one keeps the name and each other is named
    by its path. A file that is not on this machine (a run made elsewhere) cannot be told
    apart by its content: it keeps the name (the built-in file of the checkout that ran it).
    First, one scene file that configs wrote two ways (a sweep file's ``../scenes/a.yaml``, a run's
    ``/p/scenes/a.yaml``) gets one name (:func:`_one_name_per_file`)."""
    labels: dict[tuple, str] = {}  # (each distinct reference and file worked out once: a sweep's points share one)
    for r in runs:
        scene = r.results.get("scene") or {}
        key = (str(r.config.get("scene")), str(scene.get("source")), str(scene.get("name")))
        if key not in labels:
            r.named = ""
            labels[key] = r.scene_label
        r.named = labels[key]
    _one_name_per_file(runs)
    files: dict[str, set[str]] = {}
    for r in runs:
        files.setdefault(r.named, set()).add(same_file((r.results.get("scene") or {}).get("source")))
    renamed: dict[tuple[str, str], str] = {}
    for label, sources in files.items():
        if len(sources) < 2:
            continue
        if label.lower().endswith((".yaml", ".yml")):
            renamed.update({(label, src): file_name(src) for src in sources})
        else:
            renamed.update({(label, src): file_name(src) for src in _other_files(label, sources)})
    if renamed:
        for r in runs:
            r.named = renamed.get((r.named, same_file((r.results.get("scene") or {}).get("source"))), r.named)
    _by_digest(runs)


def scene_digest(run) -> tuple[str | None, bool]:
    """The digest of a run's scene inputs (:func:`~tlm.experiments.provenance.scene_identity`: its scene file,
    ``extends:`` chain, meshes and their libraries) and whether its ``results.json`` recorded it as the run read
    them (``scene_digest``, a sweep point's too); for a run or sweep point of an older tlm, which record none, that
    of the files as they are on this machine now (None where its scene file is not here), and False."""
    from tlm.experiments.provenance import scene_identity

    recorded = run.results.get("scene_digest")
    if isinstance(recorded, str) and recorded:
        return recorded, True
    source = (run.results.get("scene") or {}).get("source")
    return (scene_identity(source) if source and Path(str(source)).is_file() else None), False


def _by_digest(runs: list) -> None:
    """Where the runs of one scene name recorded different scene digests (:func:`scene_digest`: one scene file
    whose mesh, MTL or YAML was edited between them), each is named with its digest's first 8 digits too
    (``orig.yaml [9124ca48]``): one name, one scene content. A digest not recorded (an older tlm) splits none, and
    its run keeps the name (:func:`digest_notes` says why)."""
    digests: dict[str, set[str]] = {}
    for r in runs:
        got, recorded = scene_digest(r)
        if recorded:
            digests.setdefault(r.named, set()).add(got)
    for r in runs:
        got, recorded = scene_digest(r)
        if recorded and len(digests.get(r.named, ())) > 1:
            r.named = f"{r.named} [{got.removeprefix('sha256 ')[:8]}]"


def digest_notes(runs: list) -> list[str]:
    """The report's lines on runs whose scene contents differ though their scene file is one
    (:func:`_by_digest` named them apart). A run that records no digest (an older tlm's run or sweep point) is compared
    by its files as they are now, which its scene's table says (:func:`tlm.report.provenance.scene_tables`)."""
    from tlm.report.common import some

    split: dict[str, list] = {}
    for r in runs:
        base, _, tail = r.named.rpartition(" [")
        if base and tail.endswith("]") and scene_digest(r)[1]:
            split.setdefault(base, []).append(r)
    return [f"The runs of scene {name} did not read the same scene inputs (its file, its extends: chain, its "
            f"meshes and their MTL libraries: results.json scene_digest): "
            f"{some(sorted({f'{r.named} ({r.label})' for r in members}))}; their numbers are of different scenes"
            for name, members in split.items()]


def same_file(source: Any) -> str:
    """A scene file's path as one text for one file, however a run recorded it: a sweep's point
    loads ``../scenes/a.yaml`` of its sweep file's folder (``/p/exp/../scenes/a.yaml``), a run
    ``/p/scenes/a.yaml``: both are ``/p/scenes/a.yaml`` (links resolved where the file is here).
    ``"None"`` for no file."""
    import os

    if not source or str(source) == "None":
        return "None"
    return os.path.realpath(str(source).replace("\\", "/"))


def _one_name_per_file(runs: list) -> None:
    """Give the runs that loaded one scene file one name, where their configs wrote it two ways
    (``../scenes/Mirror.yaml`` in a sweep file, ``/p/scenes/Mirror.yaml`` in a run's config): its
    built-in name where one of them is that, else the file's path (:func:`file_name`). A path
    relative to a config's folder that leaves it (``../scenes/a.yaml``) tells the reader nothing:
    it is named by the file's path too."""
    names: dict[str, set[str]] = {}
    for r in runs:
        source = (r.results.get("scene") or {}).get("source")
        if source:
            names.setdefault(same_file(source), set()).add(r.named)
    chosen: dict[str, str] = {}
    for file, named in names.items():
        builtin = sorted(n for n in named if not n.lower().endswith((".yaml", ".yml")))
        if len(builtin) == 1:
            chosen[file] = builtin[0]
        elif not builtin and (len(named) > 1 or any(n.replace("\\", "/").startswith("../") for n in named)):
            chosen[file] = file_name(file)
    for r in runs:
        source = (r.results.get("scene") or {}).get("source")
        if source and same_file(source) in chosen:
            r.named = chosen[same_file(source)]


def _other_files(label: str, sources: set[str]) -> list[str]:
    """Of the scene files ``sources`` that the name ``label`` stands for, those that are another
    scene: none where the ones on this machine are all one scene (by content); else each file on
    this machine that is not the same scene as this installation's built-in ``label``."""
    from tlm.experiments.provenance import scene_identity
    from tlm.scenes.loader import scenes_dir

    here = {src: scene_identity(src) for src in sources if src != "None" and Path(src).is_file()}
    if len(set(here.values())) < 2:
        return []
    builtin = next((scenes_dir() / f"{label}{ext}" for ext in (".yaml", ".yml")
                    if (scenes_dir() / f"{label}{ext}").is_file()), None)
    mine = scene_identity(builtin) if builtin is not None else None
    return sorted(src for src, ident in here.items() if ident != mine)


def file_name(source: str) -> str:
    """A scene file the report names by its path: relative to the current folder where it lies
    under it (a user's project: ``scenes/cornell.yaml``), else as the run recorded it."""
    import os

    path = os.path.normpath(source) if Path(source).is_absolute() else source  # (/p/exp/../a.yaml: /p/a.yaml)
    try:
        return Path(path).relative_to(Path.cwd().resolve()).as_posix()
    except (ValueError, OSError):
        return path


def path_labels(paths: list[Path]) -> list[str]:
    """A label for each folder of ``paths`` that tells it from the others: its name where no other
    folder has that name, else the shortest tail of its path that no other folder's path has
    (``a/sw`` and ``b/sw`` for ``coll/a/sw`` and ``coll/b/sw``; the whole absolute path for one
    whose path ends another's), and where two paths are one folder (read twice) the later
    ``(2)``, ``(3)``... as a run's label gets. The paths are compared as absolute ones."""
    import os

    parts = [Path(os.path.abspath(p)).parts for p in paths]

    def tail(i: int, k: int) -> str:
        return Path(*parts[i][-k:]).as_posix()

    labels: list[str] = []
    for i, mine in enumerate(parts):
        others = [j for j, theirs in enumerate(parts) if theirs[-1:] == mine[-1:] and theirs != mine]
        k = 1
        while k < len(mine) and any(tail(j, k) == tail(i, k) for j in others):
            k += 1
        labels.append(tail(i, k) if others else (mine[-1] if mine else str(paths[i])))
    seen: set[str] = set()
    for i, label in enumerate(labels):
        out, n = label, 2
        while out in seen:
            out, n = f"{label} ({n})", n + 1
        seen.add(out)
        labels[i] = out
    return labels


@functools.cache
def _helps() -> dict[str, str]:
    return {k: h for k, _, h in describe()}


def _clause(text: str, stops: str, aside: bool = False) -> str:
    """``text`` up to its first character of ``stops`` outside parentheses, or with ``aside`` up to
    a parenthesis after a space too (``auto (99.5th percentile -> 1)``: ``auto``; ``floor(ln n)`` whole)."""
    depth = 0
    for i, c in enumerate(text):
        if depth == 0 and (c in stops or (aside and c == "(" and text[i - 1:i] == " ")):
            return text[:i]
        depth += (c == "(") - (c == ")")
    return text


def null_meaning(key: str, short: bool = False) -> str | None:
    """What ``null`` asks of the config key ``key``, from its help (``tlm params``): the words after
    ``null =`` up to a ``;`` (``floor(ln n), the thesis's depth`` for ``bsp.levels``), or with ``short``
    their first clause, up to a ``,`` or an aside in parentheses too (``floor(ln n)``); a parenthesis is
    kept whole. None where the help does not say."""
    found = re.search(r"null = (.+)", _helps().get(key, ""))
    if not found:
        return None
    return _clause(found.group(1), ";," if short else ";", aside=short).strip().rstrip(".") or None


def value_text(key: str, v: Any) -> str:
    """A value of the config key ``key`` as the report writes it: as its YAML does, ``null``,
    ``true``, ``[16, 16]``, with what null asks where the key's help says (``null (floor(ln n))``,
    :func:`null_meaning`); a float to 4 significant digits."""
    if v is None:
        meaning = null_meaning(key, short=True)
        return f"null ({meaning})" if meaning else "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(value_text("", x) for x in v) + "]"
    return f"{v:.4g}" if isinstance(v, float) else str(v)
