"""A reference's saved rounds are "a live process is computing it" only when one is (h481).

Since 0e37d3d the writer of ``references/<key>.partial.npz`` (``h<host>-<pid>``), alive, made ``tlm cache`` say a
live process computes it (prune and clear left it alone) and a resume say "a reference that process N is computing
now". Two misfires: a compute interrupted in a process that lives on (a notebook, a service) left its rounds marked
by a live process for as long as it lived; and a writer's id given since to another process. Now the compute's
last save as it leaves its rounds says so (``stopped``), and the writer's start (``/proc``) must be that of the
process with its id now. And the photons check's line, which ``tlm reference`` says too, says what a reference
lacks there, not "the run".
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tlm.experiments.reference_resume as reference_resume
from tests.test_probe_h474 import SCENE  # (a floor and a ceiling light, in a scene file that gives no photons)
from tlm import cache_admin
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.reference_cache import partial_info, partial_path, partial_rounds
from tlm.experiments.reference_resume import Partial, Rounds
from tlm.storage import pid_alive, process_tag

REPO = Path(__file__).resolve().parents[1]
# cycles of 2 rounds, at most 6 of them; a tolerance no cycle meets
REF = {"photons": 500, "k_nearest": 8, "tolerance": 1e-9, "min_rounds": 2, "max_rounds": 12, "spp": 2}
BASE = {"scene": "cornell", "mode": "pmap", "resolution": [4, 4], "photons": {"count": 500}, "reference": REF}
# a process that computes the reference through the API, interrupted at round 7 (cycles 1-3 saved), and lives on
CHILD = r"""
import json, sys
from tlm import api

def progress(done, change, error):
    if done == 7:
        raise KeyboardInterrupt

try:
    api.reference(json.loads(sys.argv[1]), progress=progress)
except KeyboardInterrupt:
    print("left", flush=True)
sys.stdin.read()
"""
INTERRUPTED = "6 rounds saved by an interrupted compute"


def _host() -> str:
    return process_tag().rpartition("-")[0]


def _cache(capsys, *argv: str) -> str:
    capsys.readouterr()
    assert main(["cache", *argv]) == 0
    return capsys.readouterr().out


def test_rounds_left_by_a_compute_whose_process_lives_on_are_no_live_computes(cache, tmp_path, capsys):
    env = {**os.environ, "TLM_CACHE": str(cache), "PYTHONPATH": str(REPO)}
    with open(tmp_path / "child.err", "w") as err:
        proc = subprocess.Popen([sys.executable, "-c", CHILD, json.dumps(BASE)], cwd=tmp_path, env=env, text=True,
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err)
    try:
        assert proc.stdout.readline().strip() == "left", (tmp_path / "child.err").read_text()
        (path,) = (cache / "references").glob("*.partial.npz")
        info = partial_info(path)
        assert partial_rounds(info) == 6 and info["writer"] == f"{_host()}-{proc.pid}" and pid_alive(proc.pid)
        (scanned,) = cache_admin.survey(["references"], cache)
        assert not scanned.busy and [p.partial for p in scanned.partials] == [INTERRUPTED]
        out = _cache(capsys, "clear", "--dry-run")
        assert f"would remove references/{path.name} (" in out and f"partial: {INTERRUPTED})" in out, out
        config = tmp_path / "ref.yaml"
        config.write_text(json.dumps(BASE))
        assert main(["reference", str(config), "--no-progress"]) == 1  # (not converged: the tolerance out of reach)
        assert "resuming from round 6 of a reference interrupted earlier" in capsys.readouterr().out
    finally:
        proc.stdin.close()
        try:
            proc.wait(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()


def _started(pid: int) -> int:
    line = Path(f"/proc/{pid}/stat").read_text()
    return int(line[line.rindex(")") + 2:].split()[19])


def _reheader(path: Path, **fields) -> None:
    """The saved rounds' header with ``fields`` set (None: left out), all else as it was."""
    with np.load(path) as z:
        arrays = {n: z[n] for n in z.files}
    info = {**json.loads(str(arrays["info"][()])), **fields}
    arrays["info"] = np.array(json.dumps({k: v for k, v in info.items() if v is not None}))
    np.savez(path, **arrays)


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="no /proc: a writer's start is not known")
def test_rounds_whose_writers_id_another_process_has_now_are_no_live_computes(cache, monkeypatch, capsys):
    key, pixels, parent = "cd" * 10, 4, os.getppid()
    with monkeypatch.context() as m:  # (saved by a process of this machine whose id pytest's parent has)
        m.setattr(reference_resume, "process_tag", lambda: f"{_host()}-{parent}")
        Partial(key, 2, pixels).save(Rounds(3, np.ones((pixels, 3)), np.zeros((pixels, 3)), [0.5] * 2, [0.25] * 2, 3.0))
    path, computing = partial_path(key), f"6 rounds saved so far by process {parent}, computing it now"

    def said() -> tuple[str, bool, str]:
        (scanned,) = cache_admin.survey(["references"], cache)
        lines: list[str] = []
        assert Partial(key, 2, pixels, lines.append).resume(2, 10, 1e-9) is not None
        return scanned.partials[0].partial, bool(scanned.busy), lines[0]

    _reheader(path, started=_started(parent) + 1)  # (its writer started after pytest's parent: another process)
    words, busy, line = said()
    assert (words, busy) == (INTERRUPTED, False) and "resuming from round 6 of a reference interrupted earlier" in line
    assert f"would remove references/{path.name} (" in _cache(capsys, "clear", "--dry-run")
    _reheader(path, started=_started(parent))  # (the same process)
    words, busy, line = said()
    assert (words, busy) == (computing, True) and f"of a reference that process {parent} is computing now" in line
    _reheader(path, started=None)  # (an older tlm's header: its writer's id alone, as before)
    assert said()[:2] == (computing, True)
    _reheader(path, stopped=True)  # (its compute left them: no live compute, whatever its id)
    assert said()[:2] == (INTERRUPTED, False)


REFERENCE_LINE = ("photons: a photon-map reference is the estimate of each round's photons alone, but the scene file "
                  "gives no photons (no photons:, or 0) and the config's reference.photons is null, so no photon "
                  "would be traced and the reference would have nothing to estimate (every pixel 0): add `photons: "
                  "N` to the scene file, or `reference: {photons: N}` to the config (--set reference.photons=N)")


def test_the_photons_check_of_a_reference_says_what_the_reference_lacks(tmp_path):
    from tlm.config import config_from_dict
    from tlm.experiments.loading import check_photons_given
    from tlm.scenes.loader import load_scene

    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE)
    bare = load_scene(str(scene), None, None)
    # the reference traces the scene file's count (or reference.photons): whatever the mode and photons.count
    for raw in ({"mode": "pmap"}, {"mode": "refract"}, {"mode": "pmap", "photons": {"count": 500}}):
        with pytest.raises(InputError) as e:
            check_photons_given(bare, config_from_dict(raw), of="reference")
        assert str(e.value).startswith(f"{scene.resolve()}: {REFERENCE_LINE}") and "the run" not in str(e.value)
    with pytest.raises(InputError) as e:  # (a run's line, as before)
        check_photons_given(bare, config_from_dict({"mode": "pmap"}))
    assert "so no photon would be traced and the run would have no pmap frame" in str(e.value)
    with_photons = tmp_path / "p.yaml"
    with_photons.write_text(SCENE + "photons: 500\n")
    check_photons_given(load_scene(str(with_photons), None, None), config_from_dict({}), of="reference")


@pytest.mark.parametrize("mode", ["pmap", "refract"])
def test_tlm_reference_of_a_scene_without_photons_says_the_reference_would_have_nothing(mode, tmp_path, cache, capsys):
    (tmp_path / "s.yaml").write_text(SCENE)
    config = tmp_path / "c.yaml"
    config.write_text(f"scene: s.yaml\nmode: {mode}\nresolution: [8, 8]\nreference: {{max_rounds: 4}}\n")
    assert main(["reference", str(config), "--no-progress"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"tlm: error: {(tmp_path / 's.yaml').resolve()}: {REFERENCE_LINE}"), line
    assert not (cache / "references").exists()  # (no reference of 0 computed, nor cached)
