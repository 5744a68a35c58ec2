"""Four small defects probe h466 found (h474).

* A sweep file without ``base:`` ran the built-in defaults (the Cornell box) unsaid, where ``tlm run`` refuses an
  empty config: it is refused now, naming the file and the key ``base``.
* ``--mode pmap`` of a scene file without ``photons:`` (and a null ``photons.count``) ran to exit 0 without a pmap
  frame, a warning its only trace: an error before the BSP now, naming the scene file and what to add. A config's
  own ``photons.count: 0`` still leaves the pass out on purpose.
* ``tlm scene export SCENE ex/s.yaml`` refused a folder not there yet: it makes it now, as ``--out`` does.
* ``tlm plots --configs MYDIR`` stopped at the first committed study the folder lacked: such a step is skipped now,
  a line each, and the others run.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import EnvironmentFailure, InputError
from tlm.experiments.sweep_file import load_sweep

# a floor and a ceiling light, in a scene file that gives no photons:
SCENE = ("geometry:\n"
         "  - {shape: plane, name: floor, params: {size: [2.0, 2.0]}}\n"
         "materials:\n"
         "  floor: {type: lambertian, albedo: [0.7, 0.7, 0.7]}\n"
         "parts: {floor: floor}\n"
         "lights:\n"
         "  - {type: quad, corner: [-0.2, 1.5, -0.2], edge_u: [0.4, 0, 0], edge_v: [0, 0, 0.4], power: [10, 10, 10]}\n"
         "camera: {eye: [0, 0.8, 3], target: [0, 0.5, 0], vfov: 50}\n"
         "resolution: [8, 8]\n")


# --- 1. a sweep without base ---------------------------------------------------------------------------------

@pytest.mark.parametrize("text, said", [("grid: {arch.pipelines: [1, 2]}\n", "required (none given)"),
                                        ("base:\ngrid: {arch.pipelines: [1, 2]}\n", "required (it is null)")])
def test_a_sweep_without_a_base_is_refused_naming_the_file_and_key(tmp_path, capsys, text, said):
    path = tmp_path / "nobase.yaml"
    path.write_text(text)
    assert main(["sweep", str(path), "--dry-run"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"tlm: error: {path}: base: {said}: name the run config") and "base: cornell" in line
    with pytest.raises(InputError) as e:
        load_sweep(path)
    assert e.value.key == "base"
    path.write_text("base: {scene: cornell, resolution: [8, 8]}\ngrid: {arch.pipelines: [1, 2]}\n")
    assert len(load_sweep(path).points) == 2  # (the defaults, by name)


# --- 2. mode pmap without photons ----------------------------------------------------------------------------

def test_pmap_of_a_scene_file_without_photons_is_an_error_before_any_work(tmp_path, cache, capsys):
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    out = tmp_path / "o"
    assert main(["run", str(scene), "--mode", "pmap", "--out", str(out), "--no-reference", "--no-report",
                 "--no-progress"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"tlm: error: {scene.resolve()}: photons: mode 'pmap' asks for the photon-map pass")
    assert "add `photons: N` to the scene file, or `photons: {count: N}` to the config" in line
    assert "cornell 120000" in line  # (the built-in scenes' counts, as the warning quoted them)
    assert not out.exists()
    # a config that asks for pmap in its file: the same line, naming the scene file
    config = tmp_path / "c.yaml"
    config.write_text("scene: s.yaml\nmode: pmap\n")
    assert main(["run", str(config), "--out", str(out), "--no-reference", "--no-report", "--no-progress"]) == 2
    assert f"{scene.resolve()}: photons: mode 'pmap'" in capsys.readouterr().err
    assert not out.exists()


def test_pmap_with_photons_given_or_left_out_on_purpose_passes_the_check(tmp_path):
    from tlm.config import config_from_dict
    from tlm.experiments.loading import check_photons_given
    from tlm.scenes.loader import load_scene

    scene, with_photons = tmp_path / "s.yaml", tmp_path / "p.yaml"
    scene.write_text(SCENE)
    with_photons.write_text(SCENE + "photons: 500\n")
    bare, given = load_scene(str(scene), None, None), load_scene(str(with_photons), None, None)
    for s, raw in ((given, {"mode": "pmap"}), (bare, {"mode": "pmap", "photons": {"count": 0}}),
                   (bare, {"mode": "pmap", "photons": {"count": 500}}), (bare, {"mode": "refract"})):
        check_photons_given(s, config_from_dict(raw))  # (no error)
    with pytest.raises(InputError) as e:
        check_photons_given(bare, config_from_dict({"mode": "pmap"}))
    assert e.value.key == "photons" and e.value.source == str(scene.resolve())


# --- 3. scene export into a folder not there yet ---------------------------------------------------------------

def test_scene_export_makes_the_folders_of_its_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["scene", "export", "cornell", "ex/a/box.yaml"]) == 0
    assert sorted(p.name for p in (tmp_path / "ex" / "a").iterdir()) == ["box.mtl", "box.obj", "box.yaml"]
    assert main(["scene", "export", "cornell", "ex2/box.ply"]) == 0 and (tmp_path / "ex2" / "box.ply").is_file()
    capsys.readouterr()
    (tmp_path / "afile").write_text("x")
    assert main(["scene", "export", "cornell", "afile/b/box.yaml"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == "tlm: error: afile/b/box.yaml: folder 'afile/b' cannot be made: 'afile' is a file, not a folder"


def test_an_export_that_writes_nothing_leaves_no_folder(tmp_path, monkeypatch):
    from tlm import api
    from tlm.scenes import export

    def full(*_a, **_k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(export, "write_files", full)
    with pytest.raises(EnvironmentFailure):
        api.export_scene("cornell", tmp_path / "new" / "deep" / "box.yaml")
    assert not (tmp_path / "new").exists()


# --- 4. tlm plots --configs of a folder of one's own studies ---------------------------------------------------

def _plots(tmp_path: Path, files: list[str], only=None) -> tuple[list[list[str]], list[str]]:
    from tlm import api

    configs = tmp_path / "myconfigs"
    configs.mkdir(exist_ok=True)
    for name in files:
        (configs / name).write_text(yaml.safe_dump({"base": "cornell", "grid": {"arch.pipelines": [1, 2]}}))
    ran, said = [], []

    def step(argv):
        ran.append(argv)
        return 0

    with pytest.raises(InputError) as e:  # (the fake steps write no folder: no report to write)
        api.plots(configs, tmp_path / "runs", tmp_path / "plots", only, run_command=step, say=said.append)
    said.append(str(e.value))
    return ran, said


def test_plots_skips_the_steps_whose_files_the_configs_folder_lacks(tmp_path):
    ran, said = _plots(tmp_path, ["sweep_fifo.yaml"])
    assert [argv[:2] for argv in ran] == [["sweep", str(tmp_path / "myconfigs" / "sweep_fifo.yaml")]]
    skipped = [line for line in said if ": skipped: " in line]
    assert skipped[0] == (f"== thesis: skipped: {tmp_path / 'myconfigs' / 'thesis.yaml'} is not there (--configs "
                          f"{tmp_path / 'myconfigs'} lacks it; the report shows its folder under --runs where one "
                          "exists)")
    assert len(skipped) == 11 and skipped[-1].startswith("== eq52: skipped: no scaling sweep to fit")
    assert said[-1] == f"runs: no step's folder exists under {tmp_path / 'runs'}"  # (the API's key: --runs')


def test_plots_refuses_a_folder_of_none_of_them(tmp_path):
    ran, said = _plots(tmp_path, [])
    assert ran == [] and said[-1].startswith(f"{tmp_path / 'myconfigs'}: configs: holds none of the steps' "
                                             "experiment files (thesis.yaml, scaling_ring.yaml")
