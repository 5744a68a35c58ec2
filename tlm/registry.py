"""Registries: a new radiance estimator or scheduler is one class and one YAML value.

A :class:`Registry` maps the names a config may give (``estimate.filter: disk``,
``arch.scheduler: dynamic``) to the classes that implement them. A class joins with
the registry's decorator::

    from tlm.registry import ESTIMATORS

    @ESTIMATORS.register("mine")
    class Mine(Estimator): ...

and ``estimate.filter: mine`` then selects it; the config check lists it among the
choices and suggests it for a near miss. The registry itself sits in the bottom layer
(so the config can check a value against it); the classes live in the layer that
implements them, in the built-in *provider* modules the registry imports the first time
it is asked for its names, and in any installed package that declares an entry point in
the registry's group (``[project.entry-points."tlm.estimators"]``), so a researcher's
own package can add one without editing tlm. docs/architecture.md shows both.

Such a class's code is no part of tlm's code fingerprint: :func:`plugins` lists the classes from outside
tlm that a config selects, each with its code's digest, which the cache keys, the sweep points' hashes
and a run's ``results.json`` hold (a config of tlm's own classes alone: none, its keys as before).
"""

from __future__ import annotations

import functools
import importlib
import threading
from collections.abc import Callable, Iterator
from importlib.metadata import entry_points

from tlm.errors import InputError, did_you_mean

_LOAD_LOCK = threading.RLock()  # held while a registry imports its providers (see Registry._load)


class Registry:
    """Named classes of one kind, filled by :meth:`register` and by its provider modules."""

    def __init__(self, kind: str, providers: tuple[str, ...], group: str, setting: str | None = None):
        self.kind = kind
        self.providers = providers  # modules that register the built-in classes on import
        self.group = group  # entry-point group of other packages' classes
        self.setting = setting  # the config's dotted key whose value names one (plugins), if any
        self._classes: dict[str, type] = {}
        self._dists: dict[str, tuple] = {}  # name -> (distribution, version) of the entry point that gave it
        self._plugins: dict[tuple[str, type], dict] = {}  # (name, class) -> its record (plugin)
        if setting is not None:
            REGISTRIES.append(self)
        self._loaded = False
        self._loading = False  # (set while this registry's providers are imported)

    def register(self, name: str) -> Callable[[type], type]:
        """Class decorator: the class is what the config value ``name`` selects."""
        def add(cls: type) -> type:
            have = self._classes.get(name)
            if have is not None and have is not cls and have.__qualname__ != cls.__qualname__:
                raise ValueError(f"{self.kind} {name!r} is registered twice ({have.__module__}.{have.__qualname__}"
                                 f" and {cls.__module__}.{cls.__qualname__})")
            cls.name = name
            self._classes[name] = cls
            return cls
        return add

    def _load(self) -> None:
        """Import the providers and the entry points' classes, once. A thread that asks
        while another loads waits for it (a Dask worker runs several points at once: one
        that saw a registry marked loaded but still empty rejected ``arch.scheduler:
        static``); the registry is marked loaded only when it is."""
        if self._loaded:
            return
        with _LOAD_LOCK:  # (one lock for every registry: no two threads wait on each other's)
            if self._loaded or self._loading:  # (a provider asking its own registry: what it has so far)
                return
            self._loading = True
            try:
                for module in self.providers:
                    importlib.import_module(module)
                for ep in entry_points(group=self.group):
                    cls = ep.load()
                    if ep.name not in self._classes:
                        self.register(ep.name)(cls)
                    if self._classes[ep.name] is cls and getattr(ep, "dist", None) is not None:
                        self._dists[ep.name] = (ep.dist.name, ep.dist.version)
                self._loaded = True
            finally:
                self._loading = False

    def names(self) -> tuple[str, ...]:
        """The registered names, built-in ones first in the order they were registered."""
        self._load()
        return tuple(self._classes)

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __contains__(self, name: object) -> bool:
        return name in self.names()

    def __len__(self) -> int:
        return len(self.names())

    def __getitem__(self, name: str) -> type:
        """The class of ``name``; an unknown name is an InputError listing the known ones."""
        self._load()
        try:
            return self._classes[name]
        except KeyError:
            raise InputError(f"unknown {self.kind} {name!r} (known: {', '.join(self._classes)})"
                             f"{did_you_mean(str(name), self._classes)}") from None

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {list(self._classes) if self._loaded else 'not loaded'})"

    def plugin(self, name: str) -> dict | None:
        """None where ``name``'s class is tlm's own (a module of ``tlm``: :func:`~tlm.fingerprint.code_fingerprint`
        covers it), else its record: ``name``, ``module``, ``class``, ``distribution`` and ``version`` (its entry
        point's, else the installed distribution that holds its top-level package; None where none is known) and
        ``digest`` (:func:`~tlm.fingerprint.plugin_digest`), made once per class in a process."""
        cls = self[name]
        if cls.__module__.partition(".")[0] == "tlm":
            return None
        if (name, cls) not in self._plugins:
            from tlm.fingerprint import plugin_digest

            dist, version = self._dists.get(name) or _distribution(cls.__module__.partition(".")[0])
            self._plugins[name, cls] = {"name": name, "module": cls.__module__, "class": cls.__qualname__,
                                        "distribution": dist, "version": version, "digest": plugin_digest(cls)}
        return self._plugins[name, cls]


REGISTRIES: list[Registry] = []  # every registry, in the order made (plugins)


def _distribution(top: str) -> tuple[str | None, str | None]:
    """The installed distribution that declares the top-level package ``top``, and its version, or Nones."""
    from importlib.metadata import PackageNotFoundError, version

    names = _packages().get(top) or []
    try:
        return (names[0], version(names[0])) if names else (None, None)
    except PackageNotFoundError:
        return names[0], None


@functools.cache
def _packages() -> dict[str, list[str]]:
    """:func:`importlib.metadata.packages_distributions`, read once a process: it reads every installed
    distribution's file list (0.3-1 s with 140 installed), which each plug-in class's record asked for again."""
    from importlib.metadata import packages_distributions

    return packages_distributions()


def plugins(config: dict) -> list[dict]:
    """The plug-ins that ``config`` (a resolved config: :func:`tlm.config.to_dict`, or part of one) selects: for
    each registry whose :attr:`~Registry.setting` it holds (``estimate.filter``, ``arch.scheduler``) and whose
    value names a class from outside tlm, ``{"setting": ..., **Registry.plugin(name)}``; ``[]`` where it selects
    tlm's own alone. What the cache keys and the sweep points' hashes add to tlm's code fingerprint, and what a
    run's ``results.json`` records (``plugins``)."""
    out = []
    for reg, name in zip(REGISTRIES, selected(config)):
        if isinstance(name, str) and name in reg and (found := reg.plugin(name)) is not None:
            out.append({"setting": reg.setting, **found})
    return out


def selected(config: dict) -> tuple:
    """The value ``config`` gives each registry's :attr:`~Registry.setting` (None where it has none), in
    :data:`REGISTRIES`' order: what :func:`plugins` reads of it."""
    values = [config.get(reg.setting.partition(".")[0]) for reg in REGISTRIES]
    return tuple(v.get(reg.setting.partition(".")[2]) if isinstance(v, dict) else None
                 for reg, v in zip(REGISTRIES, values))


ESTIMATORS = Registry("radiance estimator", ("tlm.render.estimators",), "tlm.estimators", "estimate.filter")
SCHEDULERS = Registry("scheduler", ("tlm.arch.schedulers",), "tlm.schedulers", "arch.scheduler")


def may_run_on(scheduler: str, in_flight: int, frames: int) -> bool:
    """Whether a stream of the scheduler ``scheduler`` (:data:`SCHEDULERS`'s name) with ``in_flight`` images and
    ``arch.frames`` = ``frames`` may run past its frames until its completions repeat (:mod:`tlm.arch.steady`): two
    images in flight, with a queue whose completions need not repeat from the warm-up on (the dynamic one), or with
    the static tiles where the frames leave a steady window (at least ``3k - 1``). One rule for the model
    (:func:`tlm.arch.model.settling`), the planner's unread keys and a run's progress bar."""
    return in_flight > 1 and (not SCHEDULERS[scheduler].periodic_from_warmup or frames >= 3 * in_flight - 1)
