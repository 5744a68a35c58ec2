"""What tlm/api.py and tlm/api_studies.py share: the experiment file a ``tlm`` command runs
(a path, or a built-in experiment's name) and the folder it writes. :mod:`tlm.api` imports
its studies and reports from :mod:`tlm.api_studies`, which therefore cannot import
:mod:`tlm.api` (a cycle): what both need is here, and :mod:`tlm.api` re-exports
:func:`experiment_path`."""

from __future__ import annotations

import contextvars
import functools
import inspect
import json
import numbers
import os
import re
import shlex
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

from tlm.config_read import nameless
from tlm.errors import InputError, did_you_mean, quoted, shell_word
from tlm.mesh_files import descriptor_name

F = TypeVar("F", bound=Callable[..., Any])


def experiment_path(ref: str | Path, command: str = "run") -> Path:
    """The experiment file that ``tlm COMMAND REF`` runs: ``ref`` when it exists, else the
    built-in experiment named ``ref``; an :class:`InputError` otherwise (a path that does
    not exist names the built-in experiment of its file name, which is not taken in its
    place; a name that is none lists them).

    ``-``: the command line's (within :func:`flags_kept`) is refused, whether or not a file of that name is here (the
    standard input's, or a file's? ``/dev/stdin`` and ``./-`` say which); a Python caller's, which names no standard
    input, is the file ``-`` as any other name is a path (``"-"``, ``"./-"`` and ``Path("-")`` alike: the file
    :func:`tlm.load_config` reads), an :class:`InputError` in the API's words where none is here."""
    from tlm.builtin import experiment_path as find
    from tlm.scenes.loader import list_scenes  # (what tlm.api.list_scenes returns)

    given = os.fspath(ref)
    if given == "-" and not flags_are_kept():  # (a caller in Python: a file's name, no standard input's)
        if Path(given).exists():
            return Path(given)
        how = "pass the config as a mapping" if command in ("run", "reference") else "a built-in experiment's name"
        raise InputError(f"no file of that name here (the Python API reads no standard input: give a file's path, "
                         f"or {how})", source=given)
    return find(given, command, list_scenes())


def shown(value: Any) -> str:
    """A value an argument was given, as an error message names it, on one short line: its
    ``repr`` for a string, a number, None or a short list of them, and for a path its text's (as
    :func:`tlm.errors.quoted` quotes them: a byte not UTF-8 as ``\\xff``); else its type
    (``a RenderResult``), not a ``repr`` of many lines (a render's, a scene's) or of no use."""
    if (value is None or isinstance(value, (str, bytes, numbers.Number, os.PathLike, list, tuple))
            or (type(value).__module__ == "numpy" and getattr(value, "ndim", None) == 0)):  # (numpy's scalars)
        text = quoted(value)
        if "\n" not in text and len(text) <= 120:
            return text
    name = type(value).__name__
    return f"{'an' if name[:1].lower() in 'aeiou' else 'a'} {name}"


def checked(value: Any, name: str, kind: type, what: str | None = None, none: str | None = None) -> Any:
    """The argument ``name``'s ``value``, checked to be of ``kind``, ``bool`` (True or False;
    numpy's bool too) or ``int`` (a whole number, numpy's too, not a bool), as that type; None
    where ``none`` says what None means. Anything else is an :class:`InputError` naming the
    argument (``reference: 'yes' is not True or False (None: the config's reference.auto)``):
    a string ``"no"`` is not taken as true, nor ``1.5`` as one worker. ``what``: what the value
    should be, in the message (default ``True or False``, ``a whole number``)."""
    if value is None and none is not None:
        return None
    if kind is bool:
        if isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")):
            return bool(value)
    elif kind is int:
        if not isinstance(value, bool) and type(value).__name__ != "bool_" and isinstance(value, numbers.Integral):
            return int(value)
    else:
        raise TypeError(f"checked: {kind!r} is not bool or int")
    what = what or ("True or False" if kind is bool else "a whole number")
    raise InputError(f"{shown(value)} is not {what}" + (f" (None: {none})" if none is not None else ""), key=name)


def folder(out: Any, key: str = "out") -> Path:
    """``out`` as the path of a folder to write; an InputError for what is not a path."""
    if not isinstance(out, (str, os.PathLike)):
        raise InputError(f"{shown(out)} is not a folder's path: name the folder to write", key=key)
    if os.fspath(out) in ("", b""):  # (Path("") is ".": said as given, not as the '.' it becomes)
        raise InputError(f"{shown(out)} is the current folder (an empty path); name a new folder", key=key)
    return Path(out)


def existing_folder(path: str | os.PathLike | None, key: str = "base") -> None:
    """An InputError naming the argument ``key`` where ``path`` (None: the working folder) is not a
    folder that is there: a relative path found from it would be looked for nowhere."""
    if path is not None and not os.path.isdir(path):
        why = "a file" if os.path.exists(path) else "not found"
        raise InputError(f"{shown(path)} is not a folder ({why}): give an existing folder (None: the working folder)",
                         key=key)


def renamed(error: InputError, key: str) -> InputError:
    """``error`` (changed in place, and returned) with its key ``key`` in its place: the message
    names the argument, ``out: ...``, where a deeper layer named the command line's flag,
    ``--out: ...`` (its line made again: :meth:`~tlm.errors.InputError.replaced`)."""
    if error.key:
        _take(error, error.replaced(key=key))
    return error


def _take(error: InputError, new: InputError) -> None:
    """``error`` made ``new`` in place (its line, message, source and key), so that the error raised on keeps its
    traceback."""
    error.args, error.message, error.source, error.key = new.args, new.message, new.source, new.key


# a flag whose argument has another name than the flag's own (--dask-wait: dask_wait)
FLAG_ARGUMENTS = {"--write": "target", "--set": "overrides"}
# --jobs, --write FILE, --truth-spp 0 (a flag and its value: truth_spp=0)
_FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*(?: [A-Z][A-Z_]*\b| -?[0-9]+(?:\.[0-9]+)?\b(?!\.[0-9]))?")
_COMMAND = re.compile(r"\btlm [a-z-]+(?: [^\s,;:()]+)* $")  # what precedes a flag of a command shown whole
# what precedes a flag that is a config's label, ``cornell.yaml, with --set`` (the overrides' ``via``: kept)
_LABEL = re.compile(r", with $")
# ``--set ITEM`` (one or more in a row) of a ``dotted.key=value`` item as :func:`~tlm.errors.shell_word` writes it
_WORD = r"""(?:'[^']*'(?:"'"'[^']*')*|[^\s'"`=]+=[^\s'"`]*)"""
_SETS = re.compile(rf"(?<![\w-])--set {_WORD}(?: --set {_WORD})*")
_SET_SETS = re.compile(r"(?<![\w-])--set sets\b")  # (``--set sets its base``: ``overrides set its base``)


def flag_argument(flag: str, names: set[str]) -> str | None:
    """The argument among ``names`` that the command line's ``flag`` (``--dask-wait``) is, or None."""
    name = FLAG_ARGUMENTS.get(flag) or (flag[2:].replace("-", "_") if flag.startswith("--") else "")
    return name if name in names else None


def negated_argument(flag: str, names: set[str]) -> str | None:
    """The argument among ``names`` that the command line's ``--no-NAME`` flag turns off
    (``--no-reference``: ``reference``, given as ``reference=False``), or None."""
    return flag_argument(f"--{flag[5:]}", names) if flag.startswith("--no-") else None


def arguments_text(text: str, names: set[str], switches: set[str] | frozenset[str] = frozenset()) -> str:
    """``text`` naming the arguments ``names`` where it named the command line's flags (``give
    --dask local``: ``give dask local``; ``--write FILE``: ``target``; a flag of a True-or-False
    argument among ``switches``, ``use --force``: ``use force=True``; a flag that turns an argument
    off, ``--no-reference``: ``reference=False``; a flag and a number, ``--truth-spp 0``:
    ``truth_spp=0``), but those of a command shown
    whole (``tlm report --formats pdf``), a config's label (``cornell.yaml, with --set``: how its
    overrides were given, :attr:`tlm.api.Config.via`) and flags of no argument of the function."""

    def kept(m: re.Match) -> bool:  # (a flag of a command shown whole, or of a config's label)
        before = text[max(0, m.start() - 60):m.start()]
        return bool(_COMMAND.search(before) or _LABEL.search(before))

    def items(m: re.Match) -> str:  # (--set render.spp=2: overrides=["render.spp=2"], as Python passes it)
        if kept(m) or "\\" in m.group(0):  # (a backslash: kept as written, which shlex would take as an escape)
            return m.group(0)
        try:
            words = [w for w in shlex.split(m.group(0)) if w != "--set"]
        except ValueError:
            return m.group(0)
        return f"overrides={json.dumps(words, ensure_ascii=False)}"

    if "overrides" in names:
        text = _SETS.sub(items, text)
        text = _SET_SETS.sub(lambda m: m.group(0) if kept(m) else "overrides set", text)

    def argument(m: re.Match) -> str:
        flag = m.group(0).split(" ")[0]
        found = flag_argument(flag, names)
        off = negated_argument(flag, names) if found is None else None
        before = text[max(0, m.start() - 60):m.start()]
        if (found is None and off is None) or _COMMAND.search(before) or _LABEL.search(before):
            return m.group(0)
        value = m.group(0)[len(flag) + 1:]
        if off is not None:
            return f"{off}=False{f' {value}' if value else ''}"
        if value[:1].isdigit() or value[:1] == "-":  # (a number given to it: as Python passes it)
            return f"{found}={value}"
        return f"{found}=True" if found in switches else found

    return _FLAG.sub(argument, text)


def as_arguments(error: InputError, names: set[str], switches: set[str] | frozenset[str] = frozenset()
                 ) -> InputError:
    """``error`` (changed in place, and returned) naming the arguments ``names`` where it named the
    command line's flags: its key (``--out: ...``: ``out: ...``), its source where that is a flag
    (``--set: 'seed' is not of the form ...``: ``overrides: ...``) and the flags in its message
    (:func:`arguments_text`; ``switches``: the True-or-False arguments, named ``force=True``), its line
    made again from them (:meth:`~tlm.errors.InputError.replaced`: its ``message`` says what its line says)."""
    name = flag_argument(str(error.key), names) if error.key else None
    if name is not None:
        renamed(error, name)
    elif str(error.key).startswith("--set ") and "overrides" in names:  # (the item refused: overrides ITEM)
        renamed(error, f"overrides {str(error.key)[6:]}")
    source = flag_argument(error.source, names) if isinstance(error.source, str) else None
    if source is not None:
        _take(error, error.replaced(source=source))
    # (its message named so, its line made again from it: ``replaced`` makes the same line, not --dask again; the
    # source, a file's path, kept as it is)
    _take(error, error.replaced(message=arguments_text(f"{error.message}", names, switches)))
    return error


_CALLED: contextvars.ContextVar[bool] = contextvars.ContextVar("tlm_api_called", default=False)
_FLAGS_KEPT: contextvars.ContextVar[bool] = contextvars.ContextVar("tlm_flags_kept", default=False)


@contextmanager
def flags_kept():
    """A block whose calls of the API keep the command line's flags in their errors
    (:func:`argument_names`): the ``tlm`` command's, which :func:`tlm.cli.main` runs within it
    (``tlm``, ``python -m tlm``, ``main([...])`` alike). Its way there is
    ``tlm.api.argument_names.flags_kept``: the command line reaches the API through :mod:`tlm.api`."""
    token = _FLAGS_KEPT.set(True)
    try:
        yield
    finally:
        _FLAGS_KEPT.reset(token)


def argument_names(func: F) -> F:
    """A public function of the API whose :class:`InputError` names its arguments as a caller
    in Python gave them: a key that is a flag of the command line (``--out``, ``--outputs``,
    ``--jobs``, ``--dask``, ``--dask-wait``, ``--dpi``, ``--formats``, ``--truth-spp``,
    ``--write``; the deeper layers share them with the commands) becomes the argument's name
    (``out``, ``dask_wait``, ``target``: :data:`FLAG_ARGUMENTS`) where ``func`` has that
    argument, and so do a source that is a flag (``--set: ...``: ``overrides: ...``) and the flags
    its text names (:func:`as_arguments`; a True-or-False argument's as ``force=True``). Within the command
    line's command (:func:`flags_kept`, which :func:`tlm.cli.main` sets) the flags stay, as the
    user typed them; a call from anywhere else (a script, a notebook, a plugin or a test helper,
    whatever its module's name) gets the arguments' names. Only the outermost call of the API
    renames (one API function calling another leaves its errors to it)."""
    parameters = inspect.signature(func).parameters
    names = set(parameters)
    switches = {n for n, p in parameters.items() if p.default is False}  # (--force: force=True)

    @functools.wraps(func)
    def call(*args: Any, **kwargs: Any) -> Any:
        if _CALLED.get():
            return func(*args, **kwargs)
        token = _CALLED.set(True)
        try:
            return func(*args, **kwargs)
        except InputError as e:
            if not _FLAGS_KEPT.get():
                as_arguments(e, names, switches)
            raise
        finally:
            _CALLED.reset(token)

    return call  # type: ignore[return-value]


def flags_are_kept() -> bool:
    """Whether this call runs within :func:`flags_kept` (the command line's command): its lines
    name the command line's flags, as the user typed them, rather than the arguments' names."""
    return _FLAGS_KEPT.get()


argument_names.flags_kept = flags_kept  # type: ignore[attr-defined]  (tlm.api re-exports argument_names)
# (the command line's way to nameless, through tlm.api as to flags_kept: tlm.api.experiment_path.nameless)
experiment_path.nameless = nameless  # type: ignore[attr-defined]


def kind_check(command: str) -> Callable[[Any, Path], None]:
    """What a loader of ``tlm COMMAND``'s experiment file calls on the data of its one read of it, and the file's
    path: :func:`refuse_other_kind` (a pipe's text, ``<(...)``, is read once: a check that read it first would
    leave the loader nothing)."""
    return functools.partial(refuse_other_kind, command=command)


def experiment_file(path: str | Path, command: str) -> Path:
    """The experiment file a study function was given, as ``tlm COMMAND PATH`` takes it
    (:func:`experiment_path`): ``path`` where it exists, else the built-in experiment of
    that name; an :class:`InputError` otherwise, for what is neither a path nor a name. Not read
    here: a file whose keys say it is another command's is refused by its loader, on the one read
    of its text (:func:`kind_check`): a pipe's (``<(...)``), read here, would be gone for the loader."""
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"{shown(path)} is not an experiment: give an experiment file's path or a built-in "
                         "experiment's name ('tlm config list')", key="path")
    return experiment_path(path, command)


# what each kind of file is (file_kind), and what each command takes, in the messages
KIND_NAMES = {"run": "a run config", "scene": "a scene file", "sweep": "a sweep file",
              "thesis": "a thesis study file", "extreme": "an extreme-cases study file",
              "granularity": "a granularity study file", "error-vs-cost": "an error-vs-cost study file",
              "sweep record": "a sweep folder's record of the sweep it ran"}
# the kinds each command takes (a command not named: its own kind)
COMMAND_KINDS = {"run": ("run", "scene"), "reference": ("run", "scene"), "calibrate": ("thesis",)}


def file_kind(raw: Any) -> tuple[str, list[str]] | None:
    """What the keys of an experiment file (its data ``raw``) say clearly it is, and the keys
    that say so: a study or a sweep (its own keys, :data:`tlm.builtin.EXPERIMENT_COMMANDS`:
    the command that takes it; with no key of a run config or a scene file beside them, and
    with ``base`` or a key that is no near miss of a run config's: ``modes`` alone is a run
    config's typo of ``mode``), ``run`` (a run config: ``scene``, or run config keys alone) or
    ``scene`` (a scene file: ``geometry`` or ``extends``, no ``scene``), ``sweep record`` (a sweep folder's
    ``sweep.yaml``: ``tlm: sweep/1``, whose ``points:`` are no error-vs-cost study's). None when they do
    not say (what the loading then reports)."""
    import dataclasses

    from tlm.builtin import EXPERIMENT_COMMANDS
    from tlm.config import RunConfig
    from tlm.scenes.loader import SCENE_KEYS

    if not isinstance(raw, dict) or not raw:
        return None
    if str(raw.get("tlm", "")).startswith("sweep/"):  # (tlm.experiments.sweep_file.Sweep.to_dict's marker)
        return "sweep record", ["tlm"]
    keys = [str(k) for k in raw]
    fields = [f.name for f in dataclasses.fields(RunConfig)]
    own = [k for k, _ in EXPERIMENT_COMMANDS if k in keys]
    others = [k for k in keys if k in fields or (k in SCENE_KEYS and k != "description")]
    if own:
        if others or not ("base" in keys or any(not did_you_mean(k, fields) for k in own)):
            return None
        return dict(EXPERIMENT_COMMANDS)[own[0]], own
    if "base" in keys:
        return None  # (a study or a sweep of no factor: its own loading names what it lacks)
    if "scene" in keys:
        return "run", ["scene"]
    if "geometry" in keys or "extends" in keys:
        return "scene", [k for k in ("geometry", "extends") if k in keys]
    if all(k in fields for k in keys):
        return "run", keys
    return None


RESOLVED = "config.resolved.yaml"  # (what a run folder, a sweep point and a study folder keep of their config)


def again_folder(path: str | Path) -> str:
    """The name of a folder for the config ``path`` (a run folder's ``config.resolved.yaml``) run again: its run
    folder's name and ``-again`` (``a-again`` for ``runs/a/config.resolved.yaml``)."""
    return f"{Path(path).absolute().parent.name or 'run'}-again"


def other_command_first(path: str | Path, command: str) -> None:
    """:func:`refuse_other_kind` of the regular file ``path`` for ``tlm COMMAND``, read here (a check made before a
    command's own read, where what it would say first is of no use for a file the command does not take: a run
    folder's ``config.resolved.yaml`` given to ``tlm sweep`` needs no ``--out``, but ``tlm run``). Nothing where it
    is no regular file (a pipe's text is read once, by its loader) or does not read as YAML (its loader says why)."""
    import yaml

    try:
        if not Path(path).is_file():
            return
        raw = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, yaml.YAMLError):
        return
    refuse_other_kind(raw, Path(path), command)


# (the command line's way to it, through tlm.api as to nameless: tlm.api.experiment_path.other_command_first)
experiment_path.other_command_first = other_command_first  # type: ignore[attr-defined]


def _not_recorded_sweep(raw: dict, named: str) -> str | None:
    """Why the file ``named`` (a sweep folder's record ``raw`` names its sweep file so), read from here, is no sweep
    file to run that sweep again with; None where it is one whose ``base``, ``set``, ``grid`` and ``zip`` are the
    record's. A file of that name of another sweep (the record itself: ``sweep.yaml`` given in its own folder, of a
    sweep file named ``sweep.yaml``) would run another sweep into the folder."""
    import yaml

    if descriptor_name(named):  # (tlm sweep <(...): /dev/fd/63 names a pipe read once, or another file now)
        return "a pipe's, read once (give the file that was piped)"
    try:
        found = yaml.safe_load(Path(named).read_text(encoding="utf-8")) if Path(named).is_file() else None
    except (OSError, ValueError, yaml.YAMLError):
        found = None
    if not isinstance(found, dict):
        where = "moved since?" if os.path.isabs(named) else "a path from the folder tlm sweep ran in"
        return f"not found from here ({where})"
    if str(found.get("tlm", "")).startswith("sweep/"):
        return "here a sweep folder's record, not a sweep file"
    base = found.get("base") if isinstance(found.get("base"), str) else None
    if ("base_file" in raw and base != raw["base_file"]) or any(
            k in raw and (found.get(k) or {}) != (raw[k] or {}) for k in ("set", "grid", "zip")):
        return "here another sweep's file (its base, set, grid or zip are not the record's)"
    return None


def _sweep_again(raw: dict, path: Path) -> str:
    """What to do with a sweep folder's ``sweep.yaml`` (``raw``, at ``path``): the ``tlm sweep`` command that runs
    its sweep file (``sweep:``) into the folder again with its ``--set`` (``overrides:``), which skips the points
    done and runs the others, and ``tlm report`` of the folder, which reads it."""
    folder = shell_word(str(Path(path).parent))
    sweep = raw.get("sweep")
    sets = [f" --set {shell_word(str(o))}" for o in raw.get("overrides") or [] if isinstance(o, str | int | float)]
    named = sweep if isinstance(sweep, str) and sweep else None
    # (the record names the sweep file as tlm sweep was given it: a relative path is from the folder it ran in, which
    # the record does not keep; one not found from here, or moved since, is no command to run as it is, nor is a file
    # of that name here of another sweep: the record itself, sweep.yaml, given in its folder, or another project's)
    why = _not_recorded_sweep(raw, named) if named is not None else None
    again = f"tlm sweep {shell_word(named) if named is not None and why is None else 'SWEEP_FILE'} --out {folder}"
    which = ("SWEEP_FILE: its sweep file, which this record does not name" if named is None else
             "its sweep file, as this record names it" if why is None else
             f"SWEEP_FILE: its sweep file, which this record names {quoted(named)}, {why}")
    return (f"to run the sweep again, or finish it (the points done are skipped): {again}{''.join(sets)} ({which}); "
            f"to read it: tlm report {folder}")


GRANULARITY_SIZES = [1, 16, 256, 4096]  # (the sizes the study file tlm granularity's error on a run config shows)


def granularity_study(path: Path) -> str:
    """The words that give the two-line study file measuring the run config ``path``'s packet sizes (h473:
    ``tlm granularity`` takes a study file, whose ``base`` names the run config, relative to the study file)."""
    name = Path(path).name
    base = name if re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.+-]*", name) else json.dumps(name)
    return (f"write a study file of two lines beside it, 'base: {base}' and 'packet_sizes: "
            f"{json.dumps(GRANULARITY_SIZES)}', and run tlm granularity on that file")


def refuse_other_kind(raw: Any, path: Path, command: str) -> None:
    """An :class:`InputError` naming the command to use when the keys of the file ``path``
    (its data ``raw``) say clearly it is for another command than ``tlm COMMAND``
    (:func:`file_kind`): ``tlm run thesis``, ``tlm sweep cornell``. A built-in experiment is
    named by its name, as ``tlm config list -l`` names it. A loader calls it on the data of its one read of
    the file (:func:`kind_check`)."""
    from tlm.builtin import configs_dir, list_experiments

    found = file_kind(raw)
    takes = COMMAND_KINDS.get(command, (command,))
    if found is None or found[0] in takes:
        return
    kind, keys = found
    # (a command to run as printed: a path with a space quoted, one that starts with '-' as ./-, no flag to argparse)
    ref, save = shell_word(f"./{path}" if str(path).startswith("-") else str(path)), ""
    try:
        if Path(path).resolve().parent == configs_dir().resolve() and Path(path).stem in list_experiments():
            ref = Path(path).stem
    except OSError:
        pass
    if nameless(path):  # (a pipe's /dev/fd/63 names nothing once read)
        ref, save = "FILE", "save it to a file and "
    wanted = " or ".join(KIND_NAMES[k] for k in takes if k in KIND_NAMES) or f"a file for 'tlm {command}'"
    # (a run folder's or a sweep point's config.resolved.yaml, run again, needs --out: tlm.cli_run.default_out)
    out = f" --out {shell_word(f'runs/{again_folder(path)}')}" if Path(path).name == RESOLVED and not save else ""
    use = save + {"run": f"run it with tlm run {ref}{out}",
                  "scene": f"render it with tlm run {ref} (its default settings), or name it in a run config's "
                           "`scene:`"}.get(kind, f"run it with tlm {kind} {ref}")
    if kind == "sweep record":
        raise InputError(f"{KIND_NAMES[kind]} (tlm: {raw['tlm']}), not {wanted}: {_sweep_again(raw, path)}",
                         source=str(path))
    if command == "granularity" and kind == "run" and not save:  # (h473: the study file that measures it)
        use += f"; to measure its packet sizes, {granularity_study(path)}"
    if command == "calibrate" and kind != "thesis":
        wanted += " (tlm calibrate fits the programs to a thesis study's scenes)"
    raise InputError(f"{KIND_NAMES[kind]} (it has {', '.join(f'{k}:' for k in keys)}), not {wanted}: {use}",
                     source=str(path))
