"""tlm's Python API, its configs: a run config loaded and checked (:func:`load_config`, as every ``tlm``
command that runs one loads it), the :class:`Config` it returns and :func:`scene_file`, which tells a scene
file from a run config.

Read them from :mod:`tlm.api` (or ``tlm``), which re-exports them: ``tlm.load_config is
tlm.api.load_config``, ``tlm.Config is tlm.api.Config``. Bad input raises :class:`~tlm.errors.InputError`
naming the file, the key and the value, and a layer is imported when a function first needs it, whole
(:func:`tlm.whole_imports.imports_whole`), as in :mod:`tlm.api`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from tlm.api_common import argument_names, experiment_path
from tlm.api_common import existing_folder as _existing_folder
from tlm.api_common import refuse_other_kind as _refuse_other_kind
from tlm.api_common import shown as _shown
from tlm.api_studies import expanded
from tlm.config import RunConfig, apply_overrides, checked, config_from_dict, plain, read_yaml, to_dict
from tlm.config_words import with_overrides
from tlm.errors import InputError, did_you_mean
from tlm.whole_imports import imports_whole

__all__ = ["Config", "Overrides", "load_config", "override_strings", "scene_file"]

Overrides = Mapping[str, Any] | Iterable[str]  # {"render.spp": 2} or ["render.spp=2"]


@dataclass(frozen=True)
class Config:
    """A checked run config (:class:`~tlm.config.RunConfig`, every parameter with its
    default: ``tlm params``) and where it came from.

    Its settings read as attributes (``cfg.render.spp``, ``cfg.scene``, ``cfg.arch``).
    ``base``: the folder the config's relative paths (``scene``, ``arch.programs``) start
    from; ``source``: the file it was read from (None for a mapping), named in error
    messages and in ``results.json``; ``overrides``: the ``dotted.key=value`` strings
    applied to it; ``scene_file``: it is a scene file's default config (``tlm run
    SCENE.yaml``); ``via``: how the overrides were given, as error messages name them
    (``the overrides`` for a mapping; ``--set`` for the command line's strings: :func:`load_config`).
    A Config made here of a RunConfig the checks did not make (``dataclasses.replace(cfg.settings, ...)``,
    ``dataclasses.replace(cfg, settings=...)``) checks it as a mapping of its values is checked
    (:func:`tlm.config.checked`: the InputError names the key and the value) and holds what those checks give.
    """

    settings: RunConfig
    base: Path
    source: str | None = None
    overrides: tuple[str, ...] = ()
    scene_file: bool = False
    via: str = "the overrides"

    def __post_init__(self) -> None:
        if not isinstance(self.settings, RunConfig):
            raise InputError(f"{_shown(self.settings)} is not a RunConfig: tlm.load_config makes a Config of a file, "
                             "a built-in name or a mapping", key="settings")
        settings = checked(self.settings)  # (one the checks made: as it is)
        if settings is not self.settings:
            object.__setattr__(self, "settings", settings)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_") or name == "settings":  # (copy and pickle look for these first)
            raise AttributeError(name)
        try:
            return getattr(self.settings, name)
        except AttributeError:  # (named as the class the caller holds, not the RunConfig it reads from)
            import dataclasses

            known = [f.name for f in (*dataclasses.fields(self), *dataclasses.fields(self.settings))]
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}"
                                 f"{did_you_mean(name, known)}") from None

    def __repr__(self) -> str:
        """One line (a notebook shows it for ``cfg``): where it came from, its overrides and
        the settings that name the run; every setting: ``cfg.settings`` or ``tlm.config.to_dict(cfg.settings)``."""
        shown = list(self.overrides[:4]) + ([f"... {len(self.overrides) - 4} more"] if len(self.overrides) > 4 else [])
        more = f", overrides=[{', '.join(shown)}]" if shown else ""
        resolution = self.settings.resolution  # (a tuple, shown as the list it is written as: [48, 48])
        shown_resolution = repr(list(resolution)) if resolution is not None else \
            f"{self._scene_resolution()!r} (the scene's)"
        return (f"Config(source={self.source!r}{more}, scene={self.settings.scene!r}, mode={self.settings.mode!r}, "
                f"resolution={shown_resolution}, seed={self.settings.seed!r})")

    def _scene_resolution(self) -> list[int] | None:
        """The resolution a render of this config uses where it sets none: its scene file's
        ``resolution`` (read, with its ``extends`` chain, not built); None where that cannot be read
        (the render's own loading then says why)."""
        from tlm.scenes.loader import read_scene_tree, resolve_scene_path

        try:
            raw, _ = read_scene_tree(resolve_scene_path(self.settings.scene, self.base), ())
        except (InputError, OSError, ValueError):
            return None
        res = raw.get("resolution")
        ok = isinstance(res, list) and len(res) == 2 and all(type(x) is int for x in res)
        return res if ok else None

    @property
    def label(self) -> str:
        """What error messages call the config: its file ("(dict)" for a mapping), with
        ", with the overrides" after overrides (``, with --set`` from the command line: :attr:`via`)."""
        source = "(dict)" if self.source is None else self.source
        return with_overrides(source, self.via) if self.overrides else source

    def updated(self, overrides: Overrides) -> Config:
        """A copy with the dotted keys of ``overrides`` set, checked again (an InputError
        names a bad key or value). A relative ``arch.programs`` among them is relative to the
        working folder, as ``tlm run --set`` takes it (the copy holds it as an absolute
        path), not to :attr:`base`."""
        return _updated(self, override_strings(overrides), self.via if self.overrides else _via(overrides, None))


def _updated(config: Config, more: list[str], via: str) -> Config:
    """:meth:`Config.updated` by the ``dotted.key=value`` strings ``more``, named ``via``."""
    config = replace(config, overrides=(*config.overrides, *more), via=via)
    raw = apply_overrides(to_dict(config.settings), more, source=via, cwd=Path.cwd())
    return replace(config, settings=config_from_dict(raw, config.label))


def _yaml_text(value: Any) -> str:
    """An override's value as YAML text: JSON (which YAML reads) of its :func:`plain` form,
    a non-finite float as YAML's ``.nan``/``.inf`` (JSON's ``NaN`` would read as a string),
    so that the checks name the value itself."""
    value = plain(value)
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if value != value else (".inf" if value > 0 else "-.inf")
    try:
        return json.dumps(value, ensure_ascii=False)  # (YAML reads JSON's surrogate escapes as two characters)
    except TypeError:
        raise InputError(f"{_shown(value)} is not a value a config holds (a number, a string, a bool, null, "
                         "or lists and mappings of them)", key="overrides") from None


def _via(overrides: Overrides | None, via: str | None) -> str:
    """What error messages call ``overrides``: ``via`` where given, else ``the overrides`` for
    a mapping (a notebook's) and ``--set`` for ``dotted.key=value`` strings (the command line's)."""
    if via is not None:
        if not isinstance(via, str) or not via.strip():
            raise InputError(f"{_shown(via)} is not a name for the overrides (the command line's: '--set')", key="via")
        return via
    return "the overrides" if isinstance(overrides, Mapping) else "--set"


def override_strings(overrides: Overrides | None) -> list[str]:
    """``dotted.key=value`` strings, from a mapping (values written as JSON, which YAML reads) or as given."""
    if overrides is None:
        return []
    if isinstance(overrides, Mapping):
        return [f"{k}={_yaml_text(v)}" for k, v in overrides.items()]
    if isinstance(overrides, str):
        raise InputError(f"{_shown(overrides)}: overrides are a mapping or a list of dotted.key=value strings",
                         key="overrides")
    if not isinstance(overrides, Iterable):
        raise InputError(f"{_shown(overrides)} is not overrides: give a mapping or a list of dotted.key=value "
                         "strings", key="overrides")
    if isinstance(overrides, (set, frozenset)):  # (applied in order: a set has none, its order may change)
        raise InputError("a set has no order, and overrides are applied in order (a key set twice: the last "
                         "one): give a list or a tuple of dotted.key=value strings, or a mapping", key="overrides")
    return [str(o) for o in overrides]


@argument_names
def scene_file(path: str | Path) -> Path | None:
    """``path`` (resolved) when it is a scene file rather than a run config: it has
    ``geometry`` (or ``extends``) and no ``scene``. None for a run config (whose own loading
    reports its typos). A file that is neither is an InputError saying what to write; one whose
    keys say it is a study or a sweep (``tlm run thesis``) names the command that takes it."""
    return _scene_of(read_yaml(Path(path)), Path(path))


def _scene_of(raw: Any, path: Path) -> Path | None:
    """:func:`scene_file` of ``path``, whose YAML (``raw``) is read already: read once (a pipe's is gone)."""
    import dataclasses

    from tlm.builtin import is_scene_mapping
    from tlm.scenes.loader import SCENE_KEYS, read_scene_tree

    _refuse_other_kind(raw, path, "run")
    if not isinstance(raw, dict) or not raw or "scene" in raw:
        return None
    if is_scene_mapping(raw):  # (tlm.builtin's rule, by which a sweep's or a study's base: takes one too)
        if not (path.is_file() and path.resolve().is_file()):  # (a pipe's text is gone once read, and a render
            # reads it again by its name: a deleted file's, /dev/stdin <<EOF's, is '/tmp/sh-thd.X (deleted)')
            raise InputError("is a scene file given as a pipe, a device or a deleted file (a here-document's), which a "
                             "render reads again (and its extends: and meshes from its folder): save it to a file and "
                             "name that", source=str(path))
        # (its keys, and its extends: chain's, checked now: a typo is its one line, before a run's note on it)
        read_scene_tree(path.resolve(), ())
        return path.resolve()
    fields = [f.name for f in dataclasses.fields(RunConfig)]
    keys = [str(k) for k in raw]
    if "base" in keys:  # (a study's or a sweep's key, whose own keys did not say which: _refuse_other_kind)
        raise InputError(f"not a run config (keys: {', '.join(keys)}): `base:` is a study's or a sweep's; run it "
                         "with its command (tlm sweep, tlm thesis, tlm extreme, ...; 'tlm config list -l' names the "
                         "command of each built-in experiment)", source=str(path))
    # keys both kinds of file have (resolution, photons) say nothing; a near miss of a config
    # key is a config's typo, which the config's own loading reports
    if any(k not in SCENE_KEYS and (k in fields or did_you_mean(k, fields)) for k in keys):
        return None
    hint = next((f"; {k!r}{did_you_mean(k, SCENE_KEYS)}" for k in keys if did_you_mean(k, SCENE_KEYS)
                 and k not in SCENE_KEYS), "")
    what = ("a scene file needs `geometry:` (a builder, a mesh or shapes: docs/scenes.md)"
            if any(k in SCENE_KEYS for k in keys) else "a scene file has `geometry:` (docs/scenes.md)")
    what += hint
    raise InputError(f"neither a run config nor a scene file (keys: {', '.join(keys)}): a config names its "
                     f"scene, `scene: cornell` or `scene: path/to/scene.yaml` (see 'tlm params'); {what}",
                     source=str(path))


@argument_names
@imports_whole
def load_config(config: str | Path | Mapping[str, Any] | RunConfig | Config, overrides: Overrides | None = None,
                *, base: str | Path | None = None, via: str | None = None) -> Config:
    """A run config, checked: from a YAML file (a run config, or a scene file, which renders
    at the default settings), a built-in experiment's name (``"cornell"``, as ``tlm run
    cornell`` takes it: :func:`experiment_path`), a mapping of its keys, or a config
    already made.

    A file that exists always wins over a built-in experiment (a folder of a built-in
    experiment's name does not hide it, as on the command line); a name is the packaged file,
    which ``source`` then names. A path that does not exist is not replaced by the built-in
    experiment of its file name (``configs/cornell.yaml`` outside a checkout): its
    :class:`InputError` names that experiment instead.

    ``overrides``: dotted keys to set, ``{"render.spp": 2}`` or ``["render.spp=2"]`` (as
    ``tlm run --set``). ``base``: where a mapping's (or a RunConfig's) relative paths start
    (default: the working folder); a file's (a built-in name's, a scene file's) start at its own
    folder (a pipe's, ``/dev/fd/N``, read once, in none: the working folder) and a Config's at its ``base``:
    another ``base`` given with one is an :class:`InputError` naming ``base``, never ignored. A relative
    ``arch.programs`` given in ``overrides`` is relative to the working folder whatever the config (a file, a
    scene file, a mapping with its ``base``, a built-in name), as ``--set`` takes it; the config then holds it
    as an absolute path. A missing file, a YAML error, an unknown key or a
    value out of range raise :class:`InputError` naming it; so does a file whose keys say it
    is a study or a sweep, which names the command that runs it (``tlm thesis thesis``).
    ``via``: what error messages call the overrides (``cornell.yaml, with the overrides:
    render.spp: ...``); default ``the overrides`` for a mapping, ``--set`` for strings (the
    command line's form).
    """
    via = _via(overrides, via)
    more = override_strings(overrides)
    config, base = expanded(config, "config"), expanded(base, "base")
    if base is not None and not isinstance(base, (str, os.PathLike)):  # (a file's and a Config's own: _own_base)
        raise InputError(f"{_shown(base)} is not a folder's path (None: the working folder)", key="base")
    _existing_folder(base, "base")
    if isinstance(config, Config):
        _own_base(config, base, "the Config's")
        settings = checked(config.settings)  # (a Config of a pickle, made by a tlm before the checks: checked now)
        config = config if settings is config.settings else replace(config, settings=settings)
        return _updated(config, more, via) if more else config
    if isinstance(config, RunConfig):
        out = Config(config, Path(base) if base is not None else Path.cwd(), via=via)
        return _updated(out, more, via) if more else out
    if isinstance(config, Mapping):
        from tlm.config import files_from, sets_scene

        folder = Path(base) if base is not None else Path.cwd()
        # (its scene file and table: absolute, as a file's are; its scene, which an override replaces, unsaid)
        raw = files_from(dict(config), folder.resolve(), not sets_scene(more))
        raw = apply_overrides(raw, more, source=via, cwd=Path.cwd()) if more else raw
        source = with_overrides("(dict)", via) if more else "(dict)"
        return Config(config_from_dict(raw, source), folder, None, tuple(more), via=via)
    if not isinstance(config, (str, os.PathLike)):
        raise InputError(f"{_shown(config)} is not a config: give a YAML file's path, a mapping of the config's keys, "
                         "a RunConfig or a Config", key="config")
    path, given = Path(config), str(config)
    if not given.strip() or not path.is_file():  # (a built-in experiment's name, else the command line's error;
        # a folder named as a built-in experiment does not hide it, as on the command line)
        path = experiment_path(config)
        given = str(path)
    raw_file = read_yaml(path)  # (read once: its kind and its settings from this one text)
    scene = _scene_of(raw_file, path)
    if scene is None:
        from tlm.config import config_from_yaml

        settings, folder = config_from_yaml(raw_file, path, more, via)
        return _own_base(Config(settings, folder, given, tuple(more), via=via), base, f"the config file {given}'s")
    source = f"scene file {scene} at the default settings"
    raw: dict[str, Any] = {"scene": str(scene)}
    if more:
        raw, source = apply_overrides(raw, more, source=via, cwd=Path.cwd()), with_overrides(source, via)
    return _own_base(Config(config_from_dict(raw, source), scene.parent, given, tuple(more), scene_file=True, via=via),
                     base, f"the scene file {given}'s")


def _own_base(config: Config, base: str | Path | None, whose: str) -> Config:
    """``config``, where ``base`` is None or its own ``config.base``: another is refused, never ignored unsaid."""
    if base is not None and Path(base).resolve() != Path(config.base).resolve():
        piped = config.source and not Path(config.source).resolve().exists()  # (/dev/fd/63: tlm.config.file_folder)
        own = f"the working folder ({config.base}; a pipe is in none)" if piped else f"its own folder ({config.base})"
        raise InputError(f"{base}: {whose} relative paths start at {own}, not at base: "
                         "base is for a mapping or a RunConfig; leave it out", key="base")
    return config
