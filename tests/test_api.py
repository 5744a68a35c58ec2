"""The Python API (tlm/api.py, re-exported by tlm): the walkthrough of docs/api.md runs as
written, the entry points are typed and documented, bad input raises the InputError the
command line turns into exit status 2, and the command line reaches the layers below only
through the API."""

from __future__ import annotations

import ast
import inspect
import re
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tlm
from tlm import api
from tlm.cli import main

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "api.md"
SMALL = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1}}


def doc_blocks() -> list[str]:
    """The ```python blocks of docs/api.md, in order."""
    return re.findall(r"^```python\n(.*?)^```", DOC.read_text(), re.S | re.M)


def test_the_walkthrough_in_docs_api_md_runs(tmp_path, monkeypatch, cache):
    """Every code block of docs/api.md, in order, in one namespace (as a notebook runs them),
    writing under tmp_path (the walkthrough's ``tempfile.mkdtemp``)."""
    monkeypatch.chdir(ROOT)  # the walkthrough reads configs/cornell.yaml
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    blocks = doc_blocks()
    assert len(blocks) >= 7
    ns: dict = {"__name__": "docs_api"}
    for i, block in enumerate(blocks):
        exec(compile(block, f"{DOC} (python block {i})", "exec"), ns)
    assert ns["work"].parent == tmp_path
    assert (ns["work"] / "run" / "results.json").is_file()
    assert (ns["work"] / "pipelines" / "sweep.csv").is_file()
    rows = ns["rows"]
    assert isinstance(rows, pd.DataFrame) and len(rows) == 2
    assert list(rows.columns[:4]) == ["point", "hash", "status", "error"]
    assert (rows["cycles.throughput"] > 0).all()


def test_the_package_re_exports_the_api():
    assert sorted(tlm.__all__) == sorted(api.__all__)
    for name in api.__all__:
        assert getattr(tlm, name) is getattr(api, name)
    assert set(api.__all__) <= set(dir(tlm))
    with pytest.raises(AttributeError, match="no attribute 'nonesuch'"):
        tlm.nonesuch  # noqa: B018


def test_no_api_name_is_hidden_by_a_subpackage():
    """``import tlm.render`` sets ``tlm.render`` to the subpackage: an API name equal to a
    module's would be the function only until then."""
    import tlm.experiments.run  # (imports tlm.render, tlm.scenes, ...)
    import tlm.report

    modules = {p.stem if p.is_file() else p.name for p in (ROOT / "tlm").iterdir()}
    assert not set(api.__all__) & modules
    assert tlm.render_image is api.render_image and inspect.ismodule(tlm.render)


def test_every_entry_point_is_typed_and_documented():
    for name in api.__all__:
        obj = getattr(api, name)
        if not inspect.isfunction(obj):
            continue
        sig = inspect.signature(obj)
        assert obj.__doc__, name
        assert sig.return_annotation is not inspect.Signature.empty, name
        untyped = [p for p in sig.parameters.values() if p.annotation is inspect.Parameter.empty]
        assert not untyped, f"{name}: {untyped}"


def test_a_missing_config_is_the_input_error_the_cli_exits_2_on(tmp_path, capsys):
    missing = tmp_path / "nope.yaml"
    with pytest.raises(tlm.InputError, match="file not found") as info:
        tlm.load_config(missing)
    assert str(missing) in str(info.value)
    assert main(["run", str(missing), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == f"tlm: error: {' '.join(str(info.value).split())}"
    with pytest.raises(tlm.InputError):
        tlm.render_image(missing)
    with pytest.raises(tlm.InputError):
        tlm.run(missing, tmp_path / "o")
    assert not (tmp_path / "o").exists()


def test_bad_keys_values_and_overrides_name_what_is_wrong():
    with pytest.raises(tlm.InputError, match=r"render\.spp.*>= 1"):
        tlm.load_config({**SMALL, "render": {"spp": 0}})
    with pytest.raises(tlm.InputError, match="rendr"):
        tlm.load_config({**SMALL, "rendr": {}})
    with pytest.raises(tlm.InputError, match=r"arch\.pipelines"):
        tlm.load_config(SMALL, {"arch.pipelines": -1})
    with pytest.raises(tlm.InputError, match="mapping or a list"):
        tlm.load_config(SMALL, "mode=pmap")
    with pytest.raises(tlm.InputError, match=r"^text: 'images,aovs'"):  # (its argument; --outputs: the CLI's)
        tlm.parse_outputs("images,aovs")


def test_a_notebook_s_values_read_as_their_plain_equivalents():
    """numpy scalars and arrays (a loop over ``np.arange``), tuples and paths are what YAML
    would give: the same config as plain numbers, lists and strings."""
    np = pytest.importorskip("numpy")
    plain = tlm.load_config({**SMALL, "render": {"spp": 2}, "arch": {"clock_hz": 3e8}})
    cfg = tlm.load_config({**SMALL, "resolution": (16, np.int32(16)), "render": {"spp": np.int64(2)},
                           "arch": {"clock_hz": np.float32(3e8)}})
    assert cfg.settings == plain.settings and type(cfg.render.spp) is int
    assert tlm.load_config({**SMALL, "resolution": np.array([16, 16])}).settings == tlm.load_config(SMALL).settings
    path = tlm.load_config({**SMALL, "scene": ROOT / "scenes" / "cornell.yaml"})
    assert path.scene == str(ROOT / "scenes" / "cornell.yaml")
    over = tlm.load_config(SMALL, {"render.spp": np.int64(3), "arch.frames": np.uint8(2), "resolution": (8, 8)})
    assert (over.render.spp, over.arch.frames, over.resolution) == (3, 2, (8, 8))
    # a path beyond the BMP survives the override's JSON (not as two lone surrogates)
    assert tlm.load_config(SMALL, {"scene": "s\U0001f642.yaml"}).scene == "s\U0001f642.yaml"
    # a NaN override is named as the NaN it is (JSON's NaN would read as the string 'NaN')
    with pytest.raises(tlm.InputError, match=r"arch\.clock_hz: nan is not finite"):
        tlm.load_config(SMALL, {"arch.clock_hz": float("nan")})
    with pytest.raises(tlm.InputError, match="not a value a config holds"):
        tlm.load_config(SMALL, {"render.spp": object()})


def test_what_is_not_a_config_a_render_or_radiance_is_named():
    for bad in (None, 5, [1, 2], b"cfg.yaml"):
        with pytest.raises(tlm.InputError, match="is not a config"):
            tlm.load_config(bad)
        with pytest.raises(tlm.InputError, match="is not a config"):
            tlm.render_image(bad)
    with pytest.raises(tlm.InputError, match="NoneType is not a render"):
        tlm.simulate(None)
    for bad in ([[1.0, 2.0]], [[1, 2], [3, 4]], "x"):
        with pytest.raises(tlm.InputError, match="not RGB radiance"):
            tlm.to_srgb(bad)
    assert tlm.to_srgb([[0.5, 0.5, 0.5]], exposure=1.0).shape == (1, 3)
    with pytest.raises(tlm.InputError, match=r"reference\.min_rounds: 10 is more than reference\.max_rounds \(2\)"):
        tlm.load_config({**SMALL, "reference": {"min_rounds": 10, "max_rounds": 2}})


def test_configs_load_from_files_mappings_and_scene_files(tmp_path):
    cfg = tlm.load_config(ROOT / "configs" / "cornell.yaml", ["mode=rcast"])
    assert cfg.mode == "rcast" and cfg.base == ROOT / "configs" and cfg.overrides == ("mode=rcast",)
    assert cfg.label.endswith("cornell.yaml, with --set") and not cfg.scene_file
    more = cfg.updated({"render.spp": 2, "arch.pipelines": 2})
    assert (more.render.spp, more.arch.pipelines, cfg.render.spp) == (2, 2, cfg.settings.render.spp)
    assert more.overrides == ("mode=rcast", "render.spp=2", "arch.pipelines=2")
    assert tlm.load_config(more) is more
    d = tlm.load_config(SMALL, base=tmp_path)
    assert (d.source, d.base, d.label, d.resolution) == (None, tmp_path, "(dict)", (16, 16))
    assert tlm.load_config(d.settings, base=tmp_path).settings == d.settings
    scene = tmp_path / "box.yaml"
    scene.write_text("extends: cornell\n")
    sc = tlm.load_config(scene)
    assert sc.scene_file and sc.scene == str(scene.resolve()) and sc.base == tmp_path
    assert tlm.scene_file(scene) == scene.resolve() and tlm.scene_file(ROOT / "configs" / "cornell.yaml") is None


def test_render_simulate_and_run_agree(tmp_path, cache):
    cfg = tlm.load_config(SMALL, base=tmp_path)
    res = tlm.render_image(cfg)
    assert res.base == tmp_path and res.timing is None
    assert res.aov["t"].shape == (16, 16) and res.work["rcast"]["tri_tests"].shape == (16, 16)
    assert res.work_totals()["rcast"]["primary_rays"] == 16 * 16
    timing = tlm.simulate(res)
    assert res.timing is None  # simulate returns the timing, the render is left as it is
    same = tlm.simulate(res, cfg.arch)
    other = tlm.simulate(res, {"arch.page_miss_cycles": 48})
    assert same.cycles == timing.cycles and other.cycles != timing.cycles
    with pytest.raises(tlm.InputError, match="pipelines"):
        tlm.simulate(res, {"pipelines": 0})
    with pytest.raises(tlm.InputError, match="arch is an ArchConfig or a mapping"):
        tlm.simulate(res, "pipelines=2")
    results = tlm.run(cfg, tmp_path / "run", outputs=[])
    assert results["cycles"] == timing.cycles
    assert res.warnings == results["warnings"]  # (the render's: what tlm run warns of, but the stream's)
    unread = tlm.render_image(cfg.updated({"estimate.k": 9}))
    assert unread.warnings == ["estimate.k=9 (in the overrides) has no effect in this run: the photon-map pass is "
                               "left out (mode 'rcast' does not include the pmap (photon-map) pass)"]
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == [".tlm-written", "config.resolved.yaml", "images",
                                                                     "results.json"]


def test_scenes_are_listed_shown_and_exported(tmp_path):
    assert "cornell" in tlm.list_scenes()
    assert tlm.scene_description("cornell").startswith("Cornell box")
    info = tlm.scene_info("cornell")
    assert info["triangles"] == 2604 and info["resolution"] == [320, 320]
    scene = tlm.export_scene("cornell", tmp_path / "c.obj")
    assert scene.n_triangles == 2604 and (tmp_path / "c.obj").stat().st_size > 0


def _tlm_imports(path: Path) -> list[tuple[str, str]]:
    """(module, name) of every ``from tlm... import name`` of ``path`` (anywhere in it)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "tlm":
            out.extend((node.module, a.name) for a in node.names)
        elif isinstance(node, ast.Import):
            out.extend((a.name, "") for a in node.names if a.name.split(".")[0] == "tlm")
    return out


def test_the_cli_reaches_the_layers_below_only_through_the_api():
    """tlm/cli.py parses and prints, and tlm/cli_signals.py ends a command (its signals, its
    one line, its exit status): besides the API and each other they import only the error
    helpers, the cache folder (for a traceback's file), a run's claim of its folder (held through
    its report) and the thesis tables' text formatting; tlm/cli_report.py (the report a command
    writes at its end, the claim of a report's folder) as cli_signals does; tlm/cli_args.py (the
    argument types and shared options) imports the API alone; tlm/cli_tables.py (the tables
    tlm thesis, tlm scaling and tlm params print, out of cli.py) as cli.py does, the thesis
    tables' text formatting among them, cli_report's one line on stderr, and the base layer's YAML
    value writer (tlm.config_words.flow_text: a default as tlm reads it back)."""
    allowed = {"tlm", "tlm.api", "tlm.errors", "tlm.storage", "tlm.claims", "tlm.caches", "tlm.experiments.thesis"}
    used = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli.py")}
    assert used <= allowed | {"tlm.cli_signals", "tlm.cli_failed", "tlm.cli_args", "tlm.cli_report", "tlm.cli_cache",
                              "tlm.cli_run", "tlm.cli_tables", "tlm.cli_parser"}, used - allowed
    running = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_run.py")}  # (what tlm run prints, out of cli.py)
    assert running <= allowed - {"tlm.experiments.thesis"}, running - allowed
    caching = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_cache.py")}  # (tlm cache: the caches' folder alone)
    assert caching <= {"tlm", "tlm.cache_admin", "tlm.caches", "tlm.errors"}, caching
    report = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_report.py")}
    assert report <= (allowed - {"tlm.experiments.thesis"}) | {"tlm.cli_signals"}, report - allowed
    ending = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_signals.py")}
    assert ending <= (allowed - {"tlm.experiments.thesis"}) | {"tlm.cli_streams"}, ending - allowed
    failing = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_failed.py")}  # (out of cli_signals)
    assert failing <= (allowed - {"tlm.experiments.thesis"}) | {"tlm.cli_signals", "tlm.cli_streams"}, failing
    streams = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_streams.py")}  # (imported before the early signals)
    assert streams == set(), streams
    arguments = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_args.py")}
    assert arguments <= {"tlm.api"}, arguments
    parsing = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_parser.py")}  # (the commands' arguments, out of cli.py)
    assert parsing <= {"tlm", "tlm.api", "tlm.cli_args", "tlm.cli_report", "tlm.errors"}, parsing
    tables = {m for m, _ in _tlm_imports(ROOT / "tlm" / "cli_tables.py")}  # (what cli.py printed of the studies)
    assert tables <= allowed | {"tlm.cli_report", "tlm.config_words"}, tables - allowed  # (h406: flow_text, base)
    thesis = {n for f in ("cli.py", "cli_tables.py") for m, n in _tlm_imports(ROOT / "tlm" / f)
              if m == "tlm.experiments.thesis"}
    assert thesis <= {"describe_rows", "describe_items", "median_words", "slowest_words"}
    commands = [n for n in ast.walk(ast.parse((ROOT / "tlm" / "cli.py").read_text()))
                if isinstance(n, ast.FunctionDef) and n.name.startswith("_cmd_")]
    assert len(commands) >= 13
    for fn in commands:  # every command calls the API
        calls = {ast.unparse(c.func) for c in ast.walk(fn) if isinstance(c, ast.Call)}
        assert any(c.startswith("api.") for c in calls), fn.name


@pytest.mark.parametrize("module", ["tlm/api.py", "tlm/api_studies.py", "tlm/api_scenes.py", "tlm/api_cache.py",
                                    "tlm/api_common.py", "tlm/cli.py", "tlm/cli_args.py", "tlm/cli_report.py",
                                    "tlm/cli_run.py", "tlm/cli_signals.py", "tlm/cli_streams.py", "tlm/cli_cache.py",
                                    "tlm/cli_tables.py", "tlm/cli_parser.py",
                                    *sorted(
    str(p.relative_to(ROOT)) for p in (ROOT / "tlm" / "experiments").glob("*.py"))])
def test_no_private_name_is_imported_from_another_module(module):
    """Progress bars, the timer and provenance have modules of their own: the experiments
    (the sweep's workers among them), the API and the CLI import public names only."""
    private = [f"{m}.{n}" for m, n in _tlm_imports(ROOT / module) if n.startswith("_") and not n.startswith("__")]
    assert private == []


def test_a_sweeps_set_checks_are_public_names_of_their_own_module():
    """The helpers on a sweep's ``--set`` strings (tlm/experiments/sweep_sets.py, out of
    sweep_file.py) are public there, the same objects sweep_file.py calls, and do as they did."""
    import tlm.experiments.sweep_file as sweep_file
    from tlm.errors import InputError
    from tlm.experiments import sweep_sets
    from tlm.experiments.sweep_sets import given_by, named, refuse_factor_sets, said_once, set_leaves

    for name in ("at_default", "given_by", "named", "refuse_factor_sets", "said_once", "set_leaves"):
        assert getattr(sweep_file, name) is getattr(sweep_sets, name), name
    assert set_leaves("estimate={k: 9, radius: 2}") == {"estimate.k": 9, "estimate.radius": 2}
    assert given_by("arch", ["arch.fifo_depth"]) and not given_by("seed", ["arch.fifo_depth"])
    assert said_once(["alone at depth 16", "alone at depth 1"]) == "alone at depth 1 or 16"
    with pytest.raises(InputError) as e:
        refuse_factor_sets(["arch={fifo_depth: 4, pipelines: 2}"], {"arch.fifo_depth": "grid"}, "s.yaml")
    assert e.value.key == "--set arch={fifo_depth: 4, pipelines: 2}" and str(e.value).endswith("--set arch.pipelines=2")
    again = named(e.value, "s.yaml with --set")
    assert again.source == "s.yaml with --set" and again.key == e.value.key and str(again).count("s.yaml") == 1


def test_config_paths_and_sweep_factors_moved_code_is_the_same_objects_there(tmp_path):
    """The files a config names (tlm/config_paths.py, out of config.py) and a sweep file's factors as
    written (tlm/experiments/sweep_factors.py, out of sweep_file.py): the same objects the old modules
    import and call (sweep_file.py by its old private names), and doing as they did."""
    import tlm.config as config
    import tlm.experiments.sweep_file as sweep_file
    from tlm.config_paths import PATH_KEYS, builtin_scenes_dir, files_from, names_scene_file, paths_from, scene_from
    from tlm.errors import InputError
    from tlm.experiments.sweep_factors import (
        assign,
        dotted_keys,
        expand,
        expand_both,
        given_once,
        keys_given,
        value_identity,
    )

    for obj in (builtin_scenes_dir, files_from, names_scene_file, paths_from, scene_from):
        assert getattr(config, obj.__name__) is obj, obj.__name__
    assert config.PATH_KEYS is PATH_KEYS == ("arch.programs",)
    for old, obj in (("_assign", assign), ("_dotted_keys", dotted_keys), ("expand", expand),
                     ("_expand_both", expand_both), ("_given_once", given_once), ("_keys_given", keys_given),
                     ("_same", value_identity)):
        assert getattr(sweep_file, old) is obj, old
    (tmp_path / "box.yaml").write_text("{}")
    assert names_scene_file("a/box") and not names_scene_file("cornell") and (builtin_scenes_dir() / "cornell.yaml")
    assert files_from({"scene": "box.yaml", "arch": {"programs": "t.yaml"}}, tmp_path) == {
        "scene": str(tmp_path / "box.yaml"), "arch": {"programs": str(tmp_path / "t.yaml")}}
    assert scene_from("cornell", [tmp_path]) == "cornell" and paths_from("seed", 1, tmp_path) == 1
    assert assign({"render": {"spp": 4}}, "render", {"light_samples": 1}) == {"render": {"spp": 4, "light_samples": 1}}
    assert keys_given("render", [{"spp": 1}, {}]) == ["render.spp"]
    assert dotted_keys({"seed": [0, 1]}, "grid", "s.yaml", lists=True) == {"seed": [0, 1]}
    assert expand({"seed": [0, 1]}, {"mode": ["rcast"]}) == [{"seed": 0, "mode": "rcast"}, {"seed": 1, "mode": "rcast"}]
    assert expand_both({"seed": [0, 1]}, {})[1] == [(0,), (1,)] and value_identity(1) != value_identity(1.0)
    with pytest.raises(InputError) as e:
        given_once({"arch.fifo_depth": [1, 16, 1]}, {}, "s.yaml")
    assert e.value.key == "grid.arch.fifo_depth" and "1 given twice" in str(e.value)


def test_storage_and_error_cost_moved_code_is_the_same_objects_there(tmp_path):
    """Strict JSON and the rows read back (tlm/storage_json.py), the folder lock (tlm/storage_lock.py),
    both out of storage.py, and the one-off clock (tlm/experiments/error_cost_clock.py, out of
    error_cost.py): the same objects the old modules import and call, and doing as they did."""
    import tlm.experiments.error_cost as error_cost
    import tlm.storage as storage
    from tlm.experiments.error_cost_clock import CompileClock
    from tlm.storage_json import finite, json_text, read_jsonl
    from tlm.storage_lock import folder_lock

    for name, obj in (("json_text", json_text), ("read_jsonl", read_jsonl), ("finite", finite),
                      ("folder_lock", folder_lock)):
        assert getattr(storage, name) is obj, name
    assert error_cost.CompileClock is CompileClock
    assert json_text({"a": [float("inf"), 1.5]}) == '{"a": [null, 1.5]}' and finite(float("nan")) is None
    (tmp_path / "r.jsonl").write_text('{"a": 1}\n{"a": 2')  # (a last line cut off: left out)
    assert read_jsonl(tmp_path / "r.jsonl") == [(1, {"a": 1})]
    with folder_lock(tmp_path):
        pass
    clock = CompileClock()
    assert clock.within(0.0, 1.0) == 0.0 and clock.spans == []


def test_the_caches_scenes_and_run_lines_moved_code_is_the_same_objects_there(cache):
    """tlm's caches (tlm/api_cache.py) and scenes (tlm/api_scenes.py), both out of api.py, and what
    ``tlm run`` prints (tlm/cli_run.py, out of cli.py): the objects tlm.api re-exports and cli.py
    calls, doing as they did."""
    import tlm.cli as cli
    from tlm.api_cache import cache_info, clear_cache, prune_cache
    from tlm.api_scenes import export_scene, list_scenes, load_scene, scene_description, scene_info
    from tlm.cli_run import blame_flag, figures3, print_run

    for obj in (cache_info, clear_cache, prune_cache, export_scene, list_scenes, load_scene, scene_description,
                scene_info):
        assert getattr(api, obj.__name__) is obj and getattr(tlm, obj.__name__) is obj, obj.__name__
    assert (cli.blame_flag, cli.figures3, cli.print_run) == (blame_flag, figures3, print_run)
    assert cache_info("tracebacks")["folder"] == str(cache) and clear_cache(dry_run=True)["removed"] == []
    with pytest.raises(tlm.InputError, match="max_size: -1 is not a size"):
        prune_cache(max_size=-1)
    assert "cornell" in list_scenes() and figures3(0.0504) == "0.0504" and figures3(1234.4) == "1234"


def test_the_timer_adds_up_stages_and_a_bar_is_drawn_only_when_asked():
    from tlm.progress import Ticking, Timer, progress_bar

    timer = Timer()
    for _ in range(2):
        with timer.stage("a"):
            pass
    with timer.stage("b"):
        sum(range(1000))
    assert set(timer.seconds) == {"a", "b"} and all(s >= 0.0 for s in timer.seconds.values())
    # a stage on several threads at once (the render's batches): its wall time, not the sum of theirs
    import threading
    import time

    started = threading.Barrier(4)

    def batch():
        with timer.stage("pass"):
            started.wait()
            time.sleep(0.2)

    t0 = time.perf_counter()
    threads = [threading.Thread(target=batch) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert 0.2 <= timer.seconds["pass"] <= time.perf_counter() - t0  # (the sum would be >= 0.8)
    with progress_bar(False, total=2) as bar, Ticking(bar, every=0.001) as ticking:
        bar.update(2)
    assert bar.disable and not ticking.thread.is_alive() and ticking.stop.is_set()


def test_provenance_names_the_versions_and_the_revision():
    from tlm.experiments.provenance import PACKAGES, git_revision, provenance, versions

    v = versions()
    assert {"python", "platform", *PACKAGES} <= set(v) and v["tlm"] != "not installed"
    rev = git_revision()
    assert rev is None or re.fullmatch(r"[0-9a-f]{40}", rev)
    p = provenance("study.yaml", 1.23456)
    assert (p["study"], p["host_seconds"], p["git_revision"]) == ("study.yaml", 1.235, rev)


def test_a_frame_is_loaded_built_and_cast_in_one_call(tmp_path):
    from tlm.experiments.loading import cast_image, load_frame
    from tlm.progress import Timer

    cfg = tlm.load_config(SMALL, base=tmp_path)
    timer = Timer()
    frame = load_frame(cfg.settings, cfg.base, cfg.label, timer=timer)
    assert set(timer.seconds) == {"load_scene", "build_bsp"}
    assert frame.scene.n_triangles == 2604 and frame.cfg is cfg.settings
    again = load_frame(cfg.settings, scene=frame.scene, timer=(t2 := Timer()))
    assert set(t2.seconds) == {"build_bsp"} and again.scene is frame.scene
    g = cast_image(frame)
    assert g.pixels.shape[0] == 16 * 16 and (g.triangle >= 0).any()
    typo = tlm.load_config({**SMALL, "scene": "cornel"})  # (the scene is read when the frame is made)
    with pytest.raises(tlm.InputError, match="cornel"):
        load_frame(typo.settings)


def test_what_is_not_a_scene_or_a_file_is_named(tmp_path):
    """The scene calls take a Scene, a built-in name or a path; anything else is an InputError
    naming the argument (it was an AttributeError deep inside), and an unknown built-in name
    has no description rather than an empty one."""
    for call in (lambda: tlm.scene_info(5), lambda: tlm.scene_info(None), lambda: tlm.export_scene(5, "x.obj")):
        with pytest.raises(tlm.InputError, match=r"^scene: .* is not a scene: give a Scene"):
            call()
    with pytest.raises(tlm.InputError, match=r"^file: None is not a file path"):
        tlm.export_scene("ring", None)
    for exposure in (-1.0, float("nan"), True, "2"):  # (a black image for no reason of the scene's)
        with pytest.raises(tlm.InputError, match=r"^exposure: .* is not a finite number >= 0"):
            tlm.to_srgb(np.ones((2, 2, 3)), exposure)
    with pytest.raises(tlm.InputError, match=r"^radiance: the radiance holds no finite value"):
        tlm.to_srgb(np.full((2, 2, 3), np.nan))
    assert tlm.to_srgb(np.zeros((2, 2, 3))).max() == 0 and tlm.to_srgb(np.ones((2, 2, 3)), 0.0).max() == 0
    with pytest.raises(tlm.InputError, match=r"'cornel' is not a built-in scene .*\(did you mean 'cornell'\?\)"):
        tlm.scene_description("cornel")
    assert tlm.scene_description("cornell") and tlm.scene_info(tlm.load_scene("ring"))["triangles"] > 0
    assert tlm.export_scene(Path("ring"), tmp_path / "r.obj").name == "ring"  # (a Path names a built-in scene too)


def test_the_experiments_reach_no_private_name_of_tlm_storage_by_its_module():
    """(h495: tlm.experiments.sweep_folder and sweep_reference called storage._writer, _hold and _release, which the
    import check above does not see: an attribute of the module, not a name imported.) Their public names:
    storage.new_writer, hold, release."""
    used = {f"{p.name}: {m}" for p in sorted((ROOT / "tlm" / "experiments").glob("*.py"))
            for m in re.findall(r"\bstorage\._[A-Za-z]\w*", p.read_text(encoding="utf-8"))}
    assert used == set(), used
