"""h397: a review of b01e82d (a sweep point's ``scene_digest``, remembered with the scene's key) and ca8eec2.

* The remembered digest was given again while the key's checks held, but those checks tell each YAML file by its
  text in universal newlines and the digest hashes its bytes: a scene file saved again with CRLF line ends (the same
  text) kept the digest of its old bytes, in the process and in ``scenes/key-*.json``, while a ``tlm run`` of the
  same files records the new bytes' digest (the report then names the point's and the run's scenes apart).
* A key file's ``digest`` that is a string but no digest (damaged) was recorded as the point's scene digest.
"""

from __future__ import annotations

import json

import pytest

from tests.test_point_digest_h393 import _mesh_scene
from tlm.experiments import frame_keys, frames
from tlm.experiments.provenance import scene_identity


@pytest.fixture(autouse=True)
def _own_cache(cache, monkeypatch):  # (tests/conftest.py; this process's memo of scene keys, emptied)
    monkeypatch.setattr(frame_keys, "_SCENE_KEYS", type(frame_keys._SCENE_KEYS)())
    return cache


def _crlf(path) -> None:
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))


def _digest(path) -> tuple[str, bool]:
    """The digest the frame key's load of ``path`` gives, and whether it loaded the scene."""
    _, scene, digest = frames._scene_key(str(path), None, None, None)
    return digest, scene is not None


@pytest.mark.parametrize("which", ["plain", "mesh"])
def test_a_scene_file_saved_with_other_line_ends_is_digested_again_in_one_process(which, tmp_path):
    if which == "mesh":
        path = _mesh_scene(tmp_path / "proj")
    else:
        path = tmp_path / "s.yaml"
        path.write_text("extends: cornell\nresolution: [8, 8]\n", encoding="utf-8")
    first, loaded = _digest(path)
    assert loaded and first == scene_identity(path)
    _crlf(path)  # (the same text: the remembered fingerprint holds, the scene not loaded again)
    now, loaded = _digest(path)
    assert not loaded and now == scene_identity(path) != first  # (was: first, the old bytes' digest)
    assert _digest(path) == (now, False)


def test_a_key_file_of_a_scene_saved_with_other_line_ends_is_digested_again(tmp_path):
    path = _mesh_scene(tmp_path / "proj")
    first, _ = _digest(path)
    (kept,) = (tmp_path / "cache" / "scenes").glob("key-*.json")
    assert json.loads(kept.read_text(encoding="utf-8"))["digest"] == first
    _crlf(path)
    frame_keys._SCENE_KEYS.clear()  # (another process: the key on disk)
    now, loaded = _digest(path)
    assert not loaded and now == scene_identity(path) != first  # (was: first)
    assert json.loads(kept.read_text(encoding="utf-8"))["digest"] == now  # (kept: digested once, not per process)


@pytest.mark.parametrize("damage", ["garbage", "", 7, None, ["sha256 0123456789abcdef"]])
def test_a_key_files_damaged_digest_is_not_recorded(damage, tmp_path):
    path = _mesh_scene(tmp_path / "proj")
    first, _ = _digest(path)
    (kept,) = (tmp_path / "cache" / "scenes").glob("key-*.json")
    body = json.loads(kept.read_text(encoding="utf-8"))
    kept.write_text(json.dumps({**body, "digest": damage}), encoding="utf-8")
    frame_keys._SCENE_KEYS.clear()
    assert _digest(path) == (first, False)  # (the scene's files digested again, its mesh not parsed)
    assert json.loads(kept.read_text(encoding="utf-8"))["digest"] == first


# ca8eec2: a faint truth was scaled (with the composite) to 1 before FLIP wherever its brightest value was below 1e-3,
# said to change nothing; but flip_evaluator holds HDR-FLIP's stop exposure at log2(x / 2**-23) where the truth's
# median luminance is below 2**-23 (half the frame dark), so its number does depend on the scale there: a half-dark
# truth peaking at 1e-5 gave 0.548 before ca8eec2 and 0.585 after, silently. Now only a truth that FLIP cannot measure
# (its luminance peaking below 2**-23: the abort) is scaled. Each case runs in a child process (the abort: exit 255).
CHILD = """
import json, sys
import numpy as np
from tlm.experiments.error_cost_truth import truth_error
from tlm.oracle import mitsuba as oracle

rng = np.random.default_rng(1)
truth = np.zeros((32, 32, 3))
truth[:, 16:] = np.linspace(0.05, 1.0, 16)[None, :, None] * np.array([1.0, 0.8, 0.6])  # half the frame dark
truth[5:9, 20:24] = 8.0
img = np.clip(truth * (1 + 0.3 * rng.standard_normal(truth.shape)), 0, None)
img[:, :16] += 0.02 * rng.random((32, 16, 3))
case, peak = sys.argv[1], float(sys.argv[2])
if case == "blue":  # (a blue truth: its luminance 0.072 of its brightest value)
    truth[..., :2] = 0.0
s = peak / truth.max()
row = truth_error((img * s).reshape(-1, 3), truth * s, np.ones((32, 32), dtype=bool))
out = {**row, "full": oracle.flip(img / truth.max(), truth / truth.max())}
if case != "blue":
    out["as_is"] = oracle.flip(img * s, truth * s)
print(json.dumps(out))
"""


def _child(case: str, peak: str) -> dict:
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", CHILD, case, peak], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("peak", ["1e-5", "1e-6"])
def test_a_faint_half_dark_truth_keeps_flips_own_number(peak):
    pytest.importorskip("flip_evaluator")
    row = _child("dark", peak)
    assert row["truth_flip"] == row["as_is"]  # (bit for bit, as before ca8eec2)
    assert row["as_is"] != pytest.approx(row["full"], rel=1e-3)  # (the scale matters to FLIP here: not rescaled)


@pytest.mark.parametrize("peak", ["1.5e-6", "1e-9"])
def test_a_truth_too_faint_for_flip_by_its_luminance_is_scaled_and_the_process_lives(peak):
    pytest.importorskip("flip_evaluator")
    row = _child("blue", peak)  # (1.5e-6 blue: luminance 1.08e-7, below 2**-23: flip_evaluator's abort)
    assert row["truth_flip"] == pytest.approx(row["full"], rel=1e-6) and 0 < row["truth_flip"] < 1
