"""The built-in experiments: the repository's ``configs/``, shipped inside the wheel as
``tlm/_configs``, found by name (``tlm run cornell_pmap``, ``tlm.load_config("cornell")``),
listed, described and copied out to edit (``tlm config list|export``)."""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Callable
from pathlib import Path

from tlm.config import file_folder, read_yaml
from tlm.config_words import yaml_kind
from tlm.errors import InputError, did_you_mean, escaped_line, quoted, shell_word

# the command that takes an experiment file, by the first of its keys found here (a study's
# own keys: tlm.experiments.*); a file with none of them is a run config ('tlm run')
EXPERIMENT_COMMANDS = (("cases", "extreme"), ("packet_sizes", "granularity"), ("points", "error-vs-cost"),
                       ("scenes", "thesis"), ("modes", "thesis"), ("grid", "sweep"), ("zip", "sweep"))


def configs_dir() -> Path:
    """Where the built-in experiment files are: inside the wheel (``tlm/_configs``), or the
    repository's ``configs/`` (as :func:`tlm.scenes.loader.scenes_dir` finds the scenes)."""
    packaged = Path(__file__).resolve().parent / "_configs"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parents[1] / "configs"


def list_experiments() -> list[str]:
    """The built-in experiments' names: the ``.yaml`` files of :func:`configs_dir`, without
    the suffix (``cornell``, ``cornell_pmap``, ``thesis``, ``sweep_fifo``)."""
    root = configs_dir()
    if not root.is_dir():
        return []
    return sorted(p.stem for p in root.glob("*.yaml") if p.is_file() and not p.name.startswith((".", "_")))


def experiment_path(ref: str, command: str = "run", scenes: list[str] | tuple[str, ...] = ()) -> Path:
    """The experiment file a command was given: ``ref`` itself when it exists (a path that
    exists always wins, but for a folder named as a built-in experiment: ``extreme`` run
    where a folder ``extreme/`` is), else the built-in experiment named ``ref`` (``cornell_pmap``: the
    packaged ``cornell_pmap.yaml``). Anything else is an InputError: a name that is no
    built-in experiment lists them; a path that does not exist whose file name is a
    built-in experiment's (``configs/cornell.yaml`` outside a checkout) names the command
    that runs the built-in one (``tlm COMMAND cornell``), and the packaged file is not
    taken in its place. ``scenes``: the built-in scene names, for a hint when ``ref`` is
    one of them (a config names a scene: it is no experiment). ``-`` is refused, whether or not a file of that
    name is here: it names no standard input (which ``/dev/stdin`` is), nor a file ``-`` that a user who meant
    the standard input would get unsaid (``./-`` names that one)."""
    if not ref.strip():
        raise InputError("an empty name names no experiment file", key="config")
    if ref == "-":  # (the Unix convention's stdin, or a file of that name: ambiguous, so neither)
        out = {"reference": "", "calibrate": " --write FILE"}.get(command, " --out DIR")  # (a pipe has no name for one)
        raise InputError(f"not the standard input here: give /dev/stdin (tlm {command} /dev/stdin{out} < FILE.yaml), "
                         "or ./- for a file named -", source=ref)
    path = Path(ref)
    names = list_experiments()
    if path.exists() and not (path.is_dir() and ref in names):  # (a folder of that name does not hide one)
        return path
    yaml_file = ref.lower().endswith((".yaml", ".yml"))
    scene = (f"; {ref} is a built-in scene, not an experiment: a config names it (`scene: {ref}`), e.g. "
             f"tlm run cornell --set scene={ref}") if ref in scenes else ""
    if not (yaml_file or "/" in ref or os.sep in ref):
        if ref in names:
            return configs_dir() / f"{ref}.yaml"
        listed = ", ".join(names) if names else "none installed"
        here = next((f for f in (f"{ref}.yaml", f"{ref}.yml") if Path(f).is_file()), None)
        hint = (f"; a file {here} is here: tlm {command} {here}" if here else did_you_mean(ref, names))
        raise InputError(f"neither a file nor a built-in experiment (built-in: {listed}; 'tlm config list -l' "
                         f"says what each one is){hint}{scene}", source=ref)
    stem = path.stem if yaml_file else path.name
    builtin_scene = scene_of_path(ref, scenes) if yaml_file else None
    if stem in names and not scene and not builtin_scene:
        raise InputError(f"not found here; the built-in experiment of that name: tlm {command} {stem} "
                         "('tlm config export' copies it out to edit)", source=ref)
    if builtin_scene:
        raise InputError(f"not found here; the built-in scene of that name: {builtin_scene} ('tlm scene export "
                         f"{builtin_scene} FILE.yaml' copies it out to edit and run; a config names it: scene: "
                         f"{builtin_scene})", source=ref)
    raise InputError(f"file not found{scene}", source=ref)


def scene_of_path(ref: str, scenes: list[str] | tuple[str, ...]) -> str | None:
    """The built-in scene a ``.yaml`` path that does not exist names: by its place under a
    ``scenes`` folder (``scenes/examples/mesh_on_floor.yaml``, a checkout's path, outside
    one: ``examples/mesh_on_floor``; ``scenes/cornell.yaml``: ``cornell``), or as a scene's
    name with its folder (``thesis/ring.yaml``: ``thesis/ring``); None for any other path
    (``cornell.yaml`` names the built-in experiment ``cornell``)."""
    parts = Path(ref).with_suffix("").parts
    under = "scenes" in parts
    if under:
        parts = parts[len(parts) - parts[::-1].index("scenes"):]
    name = "/".join(parts)
    return name if name in scenes and (under or "/" in name) else None


def base_path(base: str, folder: Path, src: str, beside: str) -> tuple[Path, bool]:
    """The run config file an experiment file's ``base: NAME`` names (a sweep's), and whether
    it is a built-in one: as ``tlm run NAME`` finds its config (:func:`experiment_path`),
    but relative to ``folder``, the experiment file's (``src``; ``beside``: what it is, for
    the messages: ``sweep file``). A path that exists wins (a folder named as a built-in
    experiment does not hide it); else a name without ``.yaml`` and ``/`` is the built-in
    experiment of that name (``base: cornell``: the packaged ``cornell.yaml``). Anything else
    is an InputError naming ``src`` and the key ``base``: a path whose file name is a
    built-in experiment's (``base: cornell.yaml`` with no such file in ``folder``) names
    ``base: cornell``, which is not taken in its place, as on the command line."""
    if not base.strip():
        raise InputError("an empty name names no run config file", source=src, key="base")
    names = list_experiments()
    file = folder / base
    if file.is_file() or (file.exists() and not file.is_dir()):  # (a pipe's, a FIFO's: read_yaml reads it once)
        return file, False
    if file.is_dir() and base not in names:  # (a folder named as a built-in experiment does not hide it)
        raise InputError(f"{quoted(base)} is a folder: name a run config file", source=src, key="base")
    yaml_file = base.lower().endswith((".yaml", ".yml"))
    export = "'tlm config export NAME FILE.yaml' copies one out to edit"
    if not (yaml_file or "/" in base or os.sep in base):
        if base in names:
            return configs_dir() / f"{base}.yaml", True
        raise InputError(f"{quoted(base)}: neither a file (relative to the {beside}) nor a built-in experiment "
                         f"('tlm config list -l' lists them; {export}){did_you_mean(base, names)}",
                         source=src, key="base")
    stem = Path(base).stem if yaml_file else Path(base).name
    if stem in names:
        raise InputError(f"{quoted(base)}: file not found (relative to the {beside}); the built-in experiment of that "
                         f"name: base: {stem} ('tlm config export {stem} FILE.yaml' copies it out to edit)",
                         source=src, key="base")
    raise InputError(f"{quoted(base)}: file not found (relative to the {beside}); a built-in experiment is named "
                     f"without .yaml (base: cornell; 'tlm config list -l' lists them; {export})",
                     source=src, key="base")


def read_base(base: object, folder: Path, src: str, beside: str,
              check_scene: Callable[[Path], object] | None = None) -> tuple[dict, str, Path]:
    """The run config an experiment file's ``base:`` gives (a sweep's, a granularity
    study's): ``(the mapping, the source its errors name, the folder its relative paths
    start at)``. A mapping is the experiment file's own (``src``, ``folder``); none is
    ``{}``; a string names a run config file or a built-in run config (:func:`base_path`,
    relative to ``folder``, the experiment file's; ``beside``: what that file is, for the
    messages). A file's relative paths start at its own folder; a built-in run config's at
    ``folder`` (it names its scene by name). A scene file (:func:`is_scene_mapping`) is taken as
    ``tlm run`` takes one, ``{scene: FILE}`` (the default settings), with a note on stderr saying so
    (:func:`_scene_base`), once ``check_scene`` (where given) read its keys: a typo is its one line, no note
    before it. A sweep or a study (a file or a built-in one)
    is refused as a base, and so is anything but a mapping or a string: InputError naming
    ``src`` and the key ``base``."""
    if isinstance(base, str):
        file, builtin = base_path(base, folder, src, beside)
        raw = read_yaml(file)
        command = next((c for key, c in EXPERIMENT_COMMANDS if key in raw), "run") if isinstance(raw, dict) else "run"
        if command != "run":
            raise InputError(f"{quoted(base)} is an experiment of 'tlm {command}', not a run config: name a run config "
                             "file, or a built-in run config ('tlm config list -l' says which command takes each one)",
                             source=src, key="base")
        if raw is None:
            raw = {}
        if not isinstance(raw, dict):
            raise InputError(f"must be a run config mapping, got {yaml_kind(raw)}", source=str(file))
        if is_scene_mapping(raw):
            return _scene_base(base, file, src, check_scene)
        return raw, str(file), folder if builtin else file_folder(file)  # (a pipe's: the working folder)
    if base is None:
        return {}, src, folder
    if not isinstance(base, dict):
        raise InputError("must be a run config mapping or the path of a run config file", source=src, key="base")
    return base, src, folder


def is_scene_mapping(raw: object) -> bool:
    """Whether a YAML file's data (``raw``) is a scene file's rather than a run config's: a mapping with
    ``geometry`` (or ``extends``) and no ``scene`` (:func:`tlm.api.scene_file`'s rule, which ``tlm run``
    takes a file by)."""
    return isinstance(raw, dict) and "scene" not in raw and ("geometry" in raw or "extends" in raw)


def _scene_base(base: str, file: Path, src: str,
                check: Callable[[Path], object] | None = None) -> tuple[dict, str, Path]:
    """:func:`read_base` of a ``base:`` that names a scene file ``file``: ``{scene: FILE}`` (absolute), as
    ``tlm run FILE`` renders it, said on stderr (``tlm: note: ...``, as ``tlm run`` says it); its keys are
    checked first by ``check`` (the scene loader's, which this layer does not import), else where the points load
    it. One given as a pipe or a device is refused: a render reads it again."""
    if not (file.is_file() and file.resolve().is_file()):
        raise InputError(f"{quoted(base)} is a scene file given as a pipe, a device or a deleted file, which a render "
                         "reads again (and its extends: and meshes from its folder): save it to a file and name that",
                         source=src, key="base")
    scene = file.resolve()
    if check is not None:
        check(scene)  # (an error here is the one line: the note is said of a scene file that reads)
    note = (f"{src}: base: {base} is a scene file: taking it as a config of that scene at the default settings, "
            f"the sweep's or study's own settings over them (a config would say `scene: {base}`; see 'tlm params')")
    sys.stderr.write(f"tlm: note: {escaped_line(note)}\n")  # (as tlm.report says its notes: stdout may be JSON)
    sys.stderr.flush()
    return {"scene": str(scene)}, f"scene file {scene} at the default settings", scene.parent


def experiment_command(name: str) -> str:
    """The ``tlm`` command that takes the built-in experiment ``name`` (``run``, ``sweep``,
    ``thesis``, ...): by its keys (:data:`EXPERIMENT_COMMANDS`)."""
    raw = read_yaml(experiment_path(name))
    keys = raw if isinstance(raw, dict) else {}
    return next((command for key, command in EXPERIMENT_COMMANDS if key in keys), "run")


def comment_description(text: str) -> str:
    """The first sentence of a YAML file's leading comment lines (joined; up to the first
    ``.`` that ends a line or is followed by a space), "" when it starts with none."""
    words = []
    for line in text.splitlines():
        if not line.startswith("#") or not line.lstrip("#").strip():
            break
        words.append(line.lstrip("#").strip())
    joined = " ".join(words)
    end = re.search(r"\.(?=\s|$)", joined)
    return joined[: end.end()] if end else joined


def experiment_description(name: str) -> str:
    """A built-in experiment's ``description:`` (a study's or a sweep's), else the first
    sentence of its leading comment (:func:`comment_description`)."""
    path = experiment_path(name)
    raw = read_yaml(path)
    if isinstance(raw, dict) and isinstance(raw.get("description"), str):
        return raw["description"]
    return comment_description(path.read_text(encoding="utf-8"))


def export_experiment(name: str, file: str | Path) -> list[Path]:
    """Copy the built-in experiment ``name`` to ``file`` (a ``.yaml`` path, to edit and run);
    returns the files written. Its comment's commands name the copy (``tlm sweep sr.yaml``,
    not the checkout's ``configs/scaling_ring.yaml``: :func:`exported_text`). A sweep whose
    ``base:`` is a run config file beside it gets that file beside ``file`` too, so that the
    copy runs as it is: both files, or neither (:func:`tlm.storage.write_files`: on a full disk,
    or a signal, the one written is removed). A file there already with the contents it would get
    (an export done before) is kept, not written again, and not returned. Refused (InputError,
    nothing written): a name that is no built-in experiment, a file that is not ``.yaml``, a folder that does not
    exist, a ``file`` of the base's own name, and a file that exists with other contents:
    ``file`` (a copy edited before is not overwritten) or the base's beside it (the user's own
    ``ring.yaml``, which the copy's ``base: ring.yaml`` would read in place of the built-in's)."""
    from tlm.storage import write_files

    names = list_experiments()
    if name not in names:
        raise InputError(f"{quoted(name)} is not a built-in experiment ({', '.join(names)}){did_you_mean(name, names)}")
    file = Path(file)
    if file.suffix.lower() not in (".yaml", ".yml"):
        raise InputError("name a .yaml file to copy the experiment into", source=str(file))
    if file.is_dir():
        raise InputError("is a folder; name a .yaml file", source=str(file))
    if not file.parent.is_dir():
        raise InputError(f"folder {quoted(file.parent)} does not exist", source=str(file))
    source = configs_dir() / f"{name}.yaml"
    copies = [(exported_text(source, name, file), file)]
    raw = read_yaml(source)
    base = raw.get("base") if isinstance(raw, dict) else None
    if isinstance(base, str) and not Path(base).is_absolute() and (source.parent / base).is_file():
        beside = file.parent / base
        if beside.resolve() == file.resolve():
            raise InputError(f"is the name of the base config {name} names (base: {base}), which is copied beside "
                             "it: name another file", source=str(file))
        copies.append(((source.parent / base).read_bytes(), beside))
    for i, (data, dst) in enumerate(copies):
        if dst.exists() and (dst.is_dir() or dst.read_bytes() != data):
            how = ("name another file (or remove it)" if i == 0 else
                   f"{file}'s base: {base} would read it in place of the built-in {name}'s base config: copy into "
                   "another folder (or remove it)")
            raise InputError(f"exists with other contents: {how}", source=str(dst))
    copies = [(data, dst) for data, dst in copies if not dst.exists()]  # (the same contents: kept)
    write_files([(dst, data) for data, dst in copies])  # (the pair or neither: a copy without its base reads no base)
    return [dst for _, dst in copies]


def exported_text(source: Path, name: str, file: Path) -> bytes:
    """The built-in experiment file ``source`` (of ``name``) as ``tlm config export`` writes it
    to ``file``: its comment lines' ``configs/NAME.yaml`` (the checkout's path of this file, in
    the commands they show) read ``file``, as given, quoted for a shell as every command tlm prints is
    (:func:`tlm.errors.shell_word`: ``'my runs/x.yaml'``; a folder of bytes not UTF-8, ``$'dir_\\xff/x.yaml'``,
    which bash gives back as those bytes and UTF-8 writes); the rest byte for byte."""
    data = source.read_bytes()
    own = f"configs/{name}.yaml"
    if own.encode() not in data:
        return data
    lines = data.decode("utf-8").splitlines(keepends=True)
    named = shell_word(str(file))  # (a command to run as shown: dir_\\xff escaped alone was bash's dir_xff)
    return "".join(line.replace(own, named) if line.lstrip().startswith("#") else line
                   for line in lines).encode("utf-8")
