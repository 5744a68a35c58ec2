"""tlm: a transaction-level model of J. Ling's 2004 ray-tracing and photon-mapping GPU.

The package's Python API is :mod:`tlm.api`, whose names read from here too
(``tlm.load_config``, ``tlm.render_image``, ``tlm.simulate``, ``tlm.run``, ``tlm.sweep``, ...;
docs/api.md walks through them). They are imported on first use, so that importing a
module of the package (``tlm.config``, a worker's ``tlm.experiments.sweep``) does not
load every layer above it. No name of the API is that of a subpackage (``tlm.render``,
``tlm.report``, ``tlm.scenes``), which would hide it once imported.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tlm.api import (  # the names of __all__, for type checkers
        MODES,
        OUTPUTS,
        Config,
        Deadlock,
        InputError,
        MaxEventsReached,
        StepsFailed,
        cache_info,
        calibrate,
        clear_cache,
        error_vs_cost,
        export_scene,
        extreme,
        granularity,
        list_scenes,
        load_config,
        load_scene,
        params,
        parse_outputs,
        plots,
        prune_cache,
        reference,
        render_image,
        run,
        run_sweep,
        scaling,
        scene_description,
        scene_file,
        scene_info,
        simulate,
        sweep,
        thesis,
        to_srgb,
        write_calibration,
        write_report,
    )

__all__ = [
    "MODES", "OUTPUTS", "Config", "Deadlock", "InputError", "MaxEventsReached", "StepsFailed", "cache_info",
    "calibrate", "clear_cache", "error_vs_cost", "export_scene", "extreme", "granularity", "list_scenes", "load_config",
    "load_scene", "params", "parse_outputs", "plots", "prune_cache", "reference", "render_image", "run", "run_sweep",
    "scaling", "scene_description", "scene_file", "scene_info", "simulate", "sweep", "thesis", "to_srgb",
    "write_calibration", "write_report",
]


def __getattr__(name: str) -> Any:
    """``tlm.<name>``: the API's name, imported on first use (PEP 562), whole: a Ctrl-C (or a
    SIGTERM a Python handler takes) during that import is held to its end, as in an API call
    (:func:`tlm.whole_imports.imports_whole`; a package cut off half imported stays broken)."""
    if name in __all__:
        api = globals().get("api")  # (set once tlm.api is imported whole)
        if api is None:
            from tlm.whole_imports import imports_whole

            api = imports_whole(_api)()
        return getattr(api, name)
    raise AttributeError(f"module 'tlm' has no attribute {name!r}")


def _api() -> Any:
    """:mod:`tlm.api`, imported."""
    from tlm import api

    return api


def __dir__() -> list[str]:
    """``dir(tlm)``: the API's names (:data:`__all__`), not this module's own (``Any``, ``TYPE_CHECKING``,
    ``annotations``) nor the submodules imported so far."""
    return sorted(__all__)
