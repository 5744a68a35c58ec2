"""The Python API from a notebook or a script (probe h205): callbacks and argument kinds checked before
any work, a lone string taken as one item, a sweep started from a script on stdin, a ``--dask local``
sweep that leaves the caller's environment as it was, studies' warnings returned rather than printed,
the scenes ``tlm scene list`` lists, a config file of ``{}``, ``~`` in paths and two messages' words."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import tlm
from tlm.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
TINY = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}}
PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1},
        "photons": {"count": 2000}, "reference": {"photons": 2345, "max_rounds": 4, "min_rounds": 2, "tolerance": 0.5}}
SWEEP = ("base: {scene: cornell, mode: rcast, resolution: [8, 8], render: {spp: 1, light_samples: 1}}\n"
         "grid:\n  arch.pipelines: [1, 2]\n")
GRANULARITY = ("base: {scene: cornell, mode: rcast, resolution: [8, 8], render: {spp: 1, light_samples: 1}, "
               "arch: {frames: 3}}\npacket_sizes: [1, 4]\n")


def _never(*args, **kwargs):
    raise AssertionError("the work started before the arguments were checked")


@pytest.mark.parametrize("name, call", [
    ("say", lambda d: tlm.run(TINY, d / "out", say=3)),
    ("say", lambda d: tlm.reference(PMAP, say=3)),
    ("warn", lambda d: tlm.sweep(d / "sw.yaml", d / "out", jobs=1, warn=3)),
    ("say", lambda d: tlm.run_sweep(d / "sw.yaml", d / "out", jobs=1, say="print")),
    ("note", lambda d: tlm.write_report([d], d / "out", note=3)),
    ("run_command", lambda d: tlm.plots(ROOT / "configs", d, d / "out", ["sweep_fifo"], run_command=None)),
    ("say", lambda d: tlm.plots(ROOT / "configs", d, d / "out", ["sweep_fifo"], run_command=_never, say=3)),
    ("warn", lambda d: tlm.thesis("thesis", d / "out", warn=3)),
    ("progress", lambda d: tlm.thesis("thesis", d / "out", progress=3)),
    ("progress", lambda d: tlm.granularity(d / "g.yaml", d / "out", progress=3)),
    ("warn", lambda d: tlm.granularity(d / "g.yaml", d / "out", warn=3)),
    ("note", lambda d: tlm.error_vs_cost("error_vs_cost", d / "out", note=3)),
    ("warn", lambda d: tlm.error_vs_cost("error_vs_cost", d / "out", warn=3)),
    ("progress", lambda d: tlm.extreme("extreme", d / "out", progress=3)),
    ("progress", lambda d: tlm.calibrate("thesis", progress=3)),
])
def test_a_callback_that_is_not_a_function_is_refused_before_any_work(tmp_path, cache, monkeypatch, name, call):
    """It was called only once the work was done (tlm.run: after the whole render), a raw TypeError."""
    from tlm.experiments import reference, run, sweep

    for module, function in ((run, "run"), (run, "render"), (reference, "make_reference"), (sweep, "run_sweep")):
        monkeypatch.setattr(module, function, _never)
    (tmp_path / "sw.yaml").write_text(SWEEP)
    (tmp_path / "g.yaml").write_text(GRANULARITY)
    with pytest.raises(InputError) as e:
        call(tmp_path)
    assert e.value.key == name and str(e.value).startswith(f"{name}: ") and "not a function" in str(e.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name, call", [
    ("out", lambda d: tlm.granularity("tlm_granularity", None)),
    ("out", lambda d: tlm.extreme("extreme", 5)),
    ("out", lambda d: tlm.thesis("thesis", None)),
    ("out", lambda d: tlm.error_vs_cost("error_vs_cost", 5)),
    ("out", lambda d: tlm.scaling([d], 5)),
    ("out", lambda d: tlm.write_report([d], out=5)),
    ("formats", lambda d: tlm.write_report([d], d / "r", formats=5)),
    ("formats", lambda d: tlm.plots(d, d, d / "r", run_command=_never, formats=5)),
    ("sweeps", lambda d: tlm.scaling(5, d / "sc")),
    ("base", lambda d: tlm.load_config({"scene": "cornell"}, base=3)),
])
def test_an_argument_of_the_wrong_kind_is_an_input_error_naming_it(tmp_path, cache, name, call):
    with pytest.raises(InputError) as e:
        call(tmp_path)
    assert e.value.key == name and str(e.value).startswith(f"{name}: ")


def test_a_lone_string_is_one_folder_or_one_step(tmp_path, cache):
    """It was taken character by character: '/: is not a sweep folder', "only: unknown step 's'"."""
    with pytest.raises(InputError) as e:
        tlm.scaling(str(tmp_path / "nosweep"), tmp_path / "sc")
    assert str(tmp_path / "nosweep") in str(e.value)
    seen = []
    with pytest.raises(InputError) as e:  # (the step ran: its folder is not there, as run_command made none)
        tlm.plots(ROOT / "configs", tmp_path / "runs", tmp_path / "p", only="sweep_fifo",
                  run_command=lambda argv: seen.append(argv) or 0)
    assert [argv[:2] for argv in seen] == [["sweep", str(ROOT / "configs" / "sweep_fifo.yaml")]]
    assert "no step's folder" in str(e.value)


def test_scaling_of_no_folder_is_refused_and_writes_nothing(tmp_path, cache):
    with pytest.raises(InputError) as e:
        tlm.scaling([], tmp_path / "sc")
    assert e.value.key == "sweeps" and "no folder given" in str(e.value)
    assert not (tmp_path / "sc").exists()
    from tlm.experiments.scaling import analyse

    with pytest.raises(InputError, match="no folder given"):
        analyse([], tmp_path / "sc2")
    assert not (tmp_path / "sc2").exists()


def test_plots_refuses_a_status_that_is_no_number_and_a_configs_folder_that_is_not_there(tmp_path, cache):
    with pytest.raises(InputError) as e:
        tlm.plots(ROOT / "configs", tmp_path / "runs", tmp_path / "p", ["sweep_fifo"], run_command=lambda a: "ok")
    assert e.value.key == "run_command" and "returned 'ok', not an exit status" in str(e.value)
    assert "see above" not in str(e.value)
    seen = []
    with pytest.raises(InputError) as e:
        tlm.plots(tmp_path / "no_configs", tmp_path / "runs", tmp_path / "p", ["sweep_fifo"],
                  run_command=lambda a: seen.append(a) or 0)
    assert seen == [] and str(tmp_path / "no_configs") in str(e.value) and "no such folder" in str(e.value)


def test_list_scenes_leaves_out_the_scenes_of_bad_input_on_purpose():
    from tlm.scenes.loader import list_scenes as every

    names = tlm.list_scenes()
    assert "cornell" in names and not [n for n in names if "/bad_" in n]
    assert "extreme/bad_scale_zero" in every() and tlm.list_scenes(bad=True) == every()
    assert tlm.scene_description("extreme/bad_scale_zero").startswith("Bad input")  # (still a built-in scene)
    with pytest.raises(InputError) as e:
        tlm.list_scenes(bad="yes")
    assert e.value.key == "bad"


def test_a_config_file_of_an_empty_mapping_is_refused_as_an_empty_file_is(tmp_path, cache, capsys):
    """A file of ``{}`` is not the defaults by mistake (e208dd7 took it so: ``tlm run empty.yaml`` rendered
    cornell); the mapping ``{}`` given in Python is."""
    from tlm.cli import main

    (tmp_path / "e.yaml").write_text("{}\n")
    for overrides in (None, {"seed": 3}):
        with pytest.raises(InputError) as e:
            tlm.load_config(tmp_path / "e.yaml", overrides)
        assert str(e.value).startswith(f"{tmp_path / 'e.yaml'}: holds an empty mapping {{}}: nothing to run")
        assert "not taken as the defaults" in str(e.value) and "is empty (nothing but comments" not in str(e.value)
    assert tlm.load_config({}).settings == tlm.load_config({"scene": "cornell"}).settings
    assert main(["run", str(tmp_path / "e.yaml"), "--out", str(tmp_path / "r")]) == 2
    assert "holds an empty mapping {}" in capsys.readouterr().err and not (tmp_path / "r").exists()
    (tmp_path / "c.yaml").write_text("# nothing\n")  # (comments alone: refused, in their own words)
    with pytest.raises(InputError, match="is empty"):
        tlm.load_config(tmp_path / "c.yaml")


@pytest.mark.slow
def test_a_tilde_in_a_path_is_the_home_folder(tmp_path, cache, monkeypatch, elsewhere):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "e.yaml").write_text("scene: cornell\n")
    assert tlm.load_config("~/e.yaml").base == (tmp_path / "home").resolve()
    tlm.run(TINY, "~/x", outputs="images")
    assert (tmp_path / "home" / "x" / "results.json").is_file() and not (elsewhere / "~").exists()


def test_the_scenes_functions_expand_a_tilde_too(tmp_path, monkeypatch, elsewhere):
    """tlm.load_scene, scene_info and export_scene took "~/s.yaml" as ./~/s.yaml."""
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    scene = tlm.export_scene("cornell", "~/c.ply")
    assert (tmp_path / "home" / "c.ply").is_file() and not (elsewhere / "~").exists()
    tlm.export_scene(scene, "~/s.yaml")
    assert (tmp_path / "home" / "s.yaml").is_file()
    assert len(tlm.load_scene("~/s.yaml").triangles) == len(scene.triangles)
    assert len(tlm.load_scene("s.yaml", base="~").triangles) == len(scene.triangles)
    assert tlm.scene_info("~/s.yaml")["triangles"] == tlm.scene_info(scene)["triangles"]


@pytest.mark.parametrize("name, call", [
    ("config", lambda d: tlm.load_config("~nosuchuser_h222/x.yaml")),
    ("base", lambda d: tlm.load_config({"scene": "cornell"}, base="~nosuchuser_h222")),
    ("out", lambda d: tlm.run(TINY, "~nosuchuser_h222/x")),
    ("sweeps", lambda d: tlm.scaling("~nosuchuser_h222/s", d / "sc")),
    ("out", lambda d: tlm.scaling([d], "~nosuchuser_h222/sc")),
    ("path", lambda d: tlm.granularity("~nosuchuser_h222/g.yaml", d / "g")),
    ("runs", lambda d: tlm.plots(ROOT / "configs", "~nosuchuser_h222", d / "p", run_command=_never)),
    ("scene", lambda d: tlm.load_scene("~nosuchuser_h222/s.yaml")),
    ("base", lambda d: tlm.load_scene("s.yaml", base="~nosuchuser_h222")),
    ("scene", lambda d: tlm.scene_info("~nosuchuser_h222/s.yaml")),
    ("file", lambda d: tlm.export_scene("cornell", "~nosuchuser_h222/s.ply")),
])
def test_a_tilde_of_no_home_folder_is_an_input_error_naming_the_argument(tmp_path, cache, name, call):
    """It was a bare ``RuntimeError: Could not determine home directory`` (or, in the scenes' functions,
    a file ``./~nosuchuser_h222/...`` looked for)."""
    with pytest.raises(InputError) as e:
        call(tmp_path)
    assert e.value.key == name and str(e.value).startswith(f"{name}: '~nosuchuser_h222")
    assert "~nosuchuser_h222 names no home folder (no such user)" in str(e.value)


@pytest.mark.slow
def test_the_studies_return_a_warning_of_their_overrides_and_print_none(tmp_path, cache, capfd):
    """They printed 'tlm: warning: --set render={} has no effect ...' on stderr themselves."""
    (tmp_path / "g.yaml").write_text(GRANULARITY)
    heard = []
    rows = tlm.granularity(tmp_path / "g.yaml", tmp_path / "g", overrides=["render={}"], warn=heard.append)
    assert rows.attrs["warnings"] == heard and len(heard) == 1
    assert heard[0].startswith("render={} (in the overrides) has no effect") and "--set" not in heard[0]
    (tmp_path / "x.yaml").write_text(
        "base: {seed: 0, resolution: [8, 8], render: {light_samples: 1, spp: 1}, arch: {frames: 2}}\n"
        "cases:\n  - name: one\n    category: geometry\n    expect: runs\n"
        "    config: {scene: cornell, mode: rcast}\n    checks: [finite]\n")
    rows = tlm.extreme(tmp_path / "x.yaml", tmp_path / "x", overrides=["render={}", "estimate.k=9"])
    assert rows[0]["passed"] and len(rows.attrs["warnings"]) == 2 and "--set" not in "".join(rows.attrs["warnings"])
    assert rows.attrs["warnings"][1].startswith("estimate.k=9 (in the overrides) has no effect in 1 of 1 cases")
    made = tlm.reference(tlm.load_config(PMAP, {"render": {}}))
    assert len(made.warnings) == 1 and made.warnings[0].startswith("render={} (in the overrides) has no effect")
    assert "warning" not in capfd.readouterr().err


def test_error_vs_cost_returns_its_warnings_and_prints_them_from_the_command_line_alone(tmp_path, cache, capfd,
                                                                                         monkeypatch):
    """It printed them on stderr from Python too, and had no ``warn=`` (granularity's and extreme's convention)."""
    from tlm.cli import main
    from tlm.experiments import error_cost

    def stop(*args, **kwargs):  # (the study's first step after its warnings: nothing rendered)
        raise InputError("stopped here", key="test")

    monkeypatch.setattr(error_cost, "check_destination", stop)
    heard = []
    with pytest.raises(InputError, match="stopped here"):
        tlm.error_vs_cost("error_vs_cost", tmp_path / "e", overrides=["render={}"], warn=heard.append)
    assert len(heard) == 1 and heard[0].startswith("render={} (in the overrides) has no effect"), heard
    assert "warning" not in capfd.readouterr().err
    error_cost.study_warning("a line  of\n two", heard.append)
    assert heard[-1] == "a line of two" and capfd.readouterr().err == ""
    assert main(["error-vs-cost", "error_vs_cost", "--set", "render={}", "--out", str(tmp_path / "c")]) == 2
    err = capfd.readouterr().err
    assert err.count("tlm: warning: --set render={} has no effect") == 1, err


@pytest.mark.slow
def test_an_overrides_refusal_of_extreme_reads_as_words():
    with pytest.raises(InputError) as e:
        tlm.extreme("extreme", "/nonexistent/x", overrides=["bsp.levels=3"])
    assert "a overrides" not in str(e.value) and "whose config wins over overrides" in str(e.value)


@pytest.mark.slow
def test_to_srgb_of_a_render_names_it_and_what_to_pass(cache):
    res = tlm.render_image(TINY)
    assert tlm.to_srgb(res).shape == (8, 8, 3)  # (a RenderResult: its composite at the run's exposure, h503)
    with pytest.raises(InputError) as e:
        tlm.to_srgb(res.radiance)
    assert "a dict is not RGB radiance" in str(e.value) and "res.radiance[pass]" in str(e.value)
    assert "shape ()" not in str(e.value)
    assert tlm.to_srgb(res.composite).shape == (8, 8, 3)


def _script(tmp_path: Path, body: str) -> str:
    return textwrap.dedent(f"""\
        import os, logging, tlm
        from pathlib import Path
        W = Path({str(tmp_path)!r})
        (W / "sw.yaml").write_text({SWEEP!r})
        """) + textwrap.dedent(body)


def _python(tmp_path: Path, args: list[str], stdin: str | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TLM_CACHE": str(tmp_path / "cache")}
    return subprocess.run([sys.executable, *args], input=stdin, capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=300)


@pytest.mark.slow
def test_a_sweep_of_worker_processes_from_a_script_on_stdin_runs_its_points(tmp_path):
    """``python - < script.py``: the workers tried to run '<stdin>' again as the main script (a
    FileNotFoundError's traceback each), and every point failed WorkerDied, exit status 0."""
    body = """\
        import threading, time
        missing, stop = [], threading.Event()
        def watch():  # (the script's other thread, reading its own __file__: deleted for the whole sweep)
            while not stop.is_set():
                try:
                    __file__
                except NameError:
                    missing.append(1)
                time.sleep(0.001)
        t = threading.Thread(target=watch)
        t.start()
        rows = tlm.sweep(W / "sw.yaml", W / "out", jobs=2)
        stop.set()
        t.join()
        print("missing", len(missing), __file__)
        print(list(rows["status"]))
        """
    done = _python(tmp_path, ["-"], _script(tmp_path, body))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "['ok', 'ok']" and "Traceback" not in done.stderr
    assert "missing 0 <stdin>" in done.stdout, done.stdout


def test_a_main_module_of_no_file_is_run_again_by_no_worker(monkeypatch):
    """``<stdin>`` (``python - < script.py``) is no script to run again, as ``python -c`` has none: its
    workers start with no main path (it was abspath('<stdin>'), which each worker failed to open). Its
    ``__file__`` stays (it was deleted for the whole sweep: the script's other threads got a NameError)."""
    import types
    from multiprocessing import spawn

    from tlm.experiments.worker_start import main_file_hidden, main_script

    main = types.ModuleType("__main__")
    main.__file__, main.__spec__ = "<stdin>", None
    monkeypatch.setitem(sys.modules, "__main__", main)
    assert main_script() is None
    own = spawn.get_preparation_data
    assert "init_main_from_path" in own("w")
    with main_file_hidden():
        assert main.__file__ == "<stdin>" and "init_main_from_path" not in spawn.get_preparation_data("w")
        with main_file_hidden():  # (another sweep's, in another thread)
            assert "init_main_from_path" not in spawn.get_preparation_data("w")
        assert "init_main_from_path" not in spawn.get_preparation_data("w")
    assert main.__file__ == "<stdin>" and spawn.get_preparation_data is own
    main.__file__ = "/some/script.py"
    with main_file_hidden():
        assert main.__file__ == "/some/script.py"
        assert spawn.get_preparation_data("w")["init_main_from_path"] == "/some/script.py"
    assert main_script() == "/some/script.py"


def test_a_dask_sweep_puts_back_only_the_variables_distributed_set(monkeypatch):
    """The whole environment was put back, undoing a variable the caller's other thread set meanwhile."""
    from tlm.experiments import executors

    for k in ("H222_D", "H222_E", "H222_U", "H222_K"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("H222_K", "before")
    with executors._host_kept() as written:
        written.update({"H222_D": "1", "H222_E": "1", "H222_K": "1"})  # (what distributed wrote)
        os.environ.update(H222_D="1", H222_E="1", H222_K="1")
        os.environ["H222_E"] = "user's"  # (another thread's, since)
        os.environ["H222_U"] = "user's"
    assert "H222_D" not in os.environ and os.environ["H222_K"] == "before"
    assert os.environ["H222_E"] == os.environ["H222_U"] == "user's"
    written = executors._pre_spawn_env()
    assert written["__DASK_PARENT_PID"] == str(os.getpid()) and "PYTHONHASHSEED" in written


@pytest.mark.slow
def test_a_dask_local_sweep_leaves_the_environment_and_the_loggers_as_they_were(tmp_path):
    pytest.importorskip("distributed")
    body = """\
        def main():
            names = ("distributed", "tornado", "bokeh")
            env = dict(os.environ)
            loggers = [(len(logging.getLogger(n).handlers), logging.getLogger(n).propagate) for n in names]
            rows = tlm.sweep(W / "sw.yaml", W / "out", dask="local", jobs=2)
            assert list(rows["status"]) == ["ok", "ok"], rows
            changed = {k for k in set(env) | set(os.environ) if env.get(k) != os.environ.get(k)}
            print("changed", sorted(changed))
            print("loggers", [(len(logging.getLogger(n).handlers), logging.getLogger(n).propagate) for n in names]
                  == loggers)
        if __name__ == "__main__":
            main()
        """
    (tmp_path / "s.py").write_text(_script(tmp_path, body))
    done = _python(tmp_path, [str(tmp_path / "s.py")])
    assert done.returncode == 0, done.stderr
    assert "changed []" in done.stdout and "loggers True" in done.stdout, done.stdout
