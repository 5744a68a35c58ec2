"""The Mitsuba version of a cached ground truth, and the self-digests of references' and ground truths' meta.json
(h528, found by a cache probe): after ``pip install -U mitsuba`` an image rendered by the old version was read as
the new one's; a byte changed in a reference's or a ground truth's ``meta.json`` (its rounds, its spp) was read
back with no word, where a functional sidecar's is told by its own sha256 (fb96772)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tlm.errors import InputError
from tlm.experiments import reference_cache as rc
from tlm.fingerprint import META_SEAL, sealed
from tlm.oracle import mitsuba as om
from tlm.scenes.loader import load_scene


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("tlm: warning: ")]


# ---------------------------------------------------------------- the Mitsuba version of a ground truth


@pytest.fixture
def fake_mitsuba(monkeypatch):
    """Mitsuba's version (settable, or None: not installed) and renders counted, without Mitsuba."""
    state = {"version": "3.5.0", "renders": 0}

    def version():
        if state["version"] is None:
            raise InputError("the Mitsuba oracle needs the optional package mitsuba", key="oracle")
        return state["version"]

    def render(scene, **kwargs):
        state["renders"] += 1
        return np.full((scene.camera.height, scene.camera.width, 3), float(state["renders"]))

    monkeypatch.setattr(om, "mitsuba_version", version)
    monkeypatch.setattr(om, "render", render)
    monkeypatch.setattr(om, "_OTHER_SAID", set())
    return state


def test_a_ground_truth_of_another_mitsuba_is_rendered_again_and_one_without_mitsuba_is_used(
        cache, fake_mitsuba, capsys):
    scene = load_scene("cornell", None, [8, 6])
    _, meta = om.ground_truth(scene, "path", spp=4)
    assert fake_mitsuba["renders"] == 1 and meta["mitsuba_version"] == "3.5.0"
    om.ground_truth(scene, "path", spp=4)  # (the same version: read)
    assert fake_mitsuba["renders"] == 1 and not _warnings(capsys.readouterr().err)

    fake_mitsuba["version"] = "3.6.2"  # (pip install -U mitsuba)
    assert om.ground_truth(scene, "path", spp=4, compute=False) is None  # (was: the old version's image)
    again, meta2 = om.ground_truth(scene, "path", spp=4)
    assert fake_mitsuba["renders"] == 2 and meta2["mitsuba_version"] == "3.6.2" and again.max() == 2.0
    said = _warnings(capsys.readouterr().err)
    assert said == [f"tlm: warning: the Mitsuba ground truth {meta['key']} cached in {cache / 'oracle'} was "
                    "rendered by Mitsuba 3.5.0, not by the Mitsuba installed (3.6.2): not used; rendered again by "
                    "this one where it is computed"], said  # (once: the read with compute=False said it)
    assert json.loads((cache / "oracle" / meta["key"] / "meta.json").read_text())["mitsuba_version"] == "3.6.2"

    fake_mitsuba["version"] = None  # (not installed: the cached one is used, whatever rendered it)
    found, meta3 = om.ground_truth(scene, "path", spp=4)
    assert fake_mitsuba["renders"] == 2 and meta3 == meta2 and found.max() == 2.0
    assert not _warnings(capsys.readouterr().err)


# ---------------------------------------------------------------- meta.json sealed


def _reference(key: str = "ab" * 8):
    rc.save_reference(key, np.ones((4, 6, 3)), {"rounds": 8, "relative_standard_error": 0.01, "converged": True})
    return rc.cache_dir() / key


def _truth(key: str = "cd" * 10):
    return om.save_ground_truth(key, np.ones((4, 6, 3)), {"scene": "cornell", "spp": 64, "width": 6, "height": 4,
                                                          "mitsuba_version": "3.5.0"})


def _edit(folder, old: str, new: str) -> None:
    path = folder / "meta.json"
    text = path.read_text()
    assert text.count(old) == 1, text
    path.write_text(text.replace(old, new))


def test_meta_json_holds_its_own_digest(cache):
    for folder in (_reference(), _truth()):
        meta = json.loads((folder / "meta.json").read_text())
        assert list(meta)[-1] == META_SEAL and meta == sealed(meta, META_SEAL)
        assert meta["format"] in ("reference-meta/2", "ground-truth-meta/2")


@pytest.mark.parametrize("kind", ["reference", "truth"])
def test_a_byte_changed_in_meta_json_is_a_damaged_entry_removed(kind, cache, capsys):
    if kind == "reference":
        folder = _reference()
        _edit(folder, '"rounds": 8', '"rounds": 9')  # (still JSON, still a whole number: was read as 9 rounds)
        load, what, again = (lambda: rc.load_reference(folder.name)), "reference", "'tlm reference' computes it again"
    else:
        folder = _truth()
        _edit(folder, '"spp": 64', '"spp": 65')
        load, what, again = (lambda: om.load_ground_truth(folder.name)), "Mitsuba ground-truth", \
            "it is rendered again when next needed"
    capsys.readouterr()
    assert load() is None
    assert _warnings(capsys.readouterr().err) == [
        f"tlm: warning: damaged {what} cache entry {folder / 'meta.json'} (its content differs from its "
        f"'{META_SEAL}'): removed; {again}"]
    assert not folder.exists()


def test_a_meta_json_without_its_digest_or_its_format_is_damaged(cache, capsys):
    for folder, drop, why in ((_reference(), META_SEAL, f"it has no '{META_SEAL}'"),
                              (_truth(), "format", "it has no 'format'")):
        meta = json.loads((folder / "meta.json").read_text())
        del meta[drop]
        (folder / "meta.json").write_text(json.dumps(meta))
        capsys.readouterr()
        load = rc.load_reference if folder.parent.name == "references" else om.load_ground_truth
        assert load(folder.name) is None
        (line,) = _warnings(capsys.readouterr().err)
        assert f"cache entry {folder / 'meta.json'} ({why}): removed" in line, line
        assert not folder.exists()


def test_an_entry_of_before_the_seals_is_used_sealed_as_read(cache, capsys, monkeypatch):
    from tlm import fingerprint

    monkeypatch.setattr(fingerprint, "_OLDER", set())
    folders = (_reference(), _truth())
    for folder in folders:  # (as the tlm before h528 wrote it: no format, no digest)
        meta = json.loads((folder / "meta.json").read_text())
        (folder / "meta.json").write_text(json.dumps({k: v for k, v in meta.items() if k not in ("format", META_SEAL)},
                                                     indent=2) + "\n")
    capsys.readouterr()
    for _ in range(2):
        assert rc.load_reference(folders[0].name)[1]["rounds"] == 8
        assert om.load_ground_truth(folders[1].name)[1]["spp"] == 64
    said = _warnings(capsys.readouterr().err)
    assert said == [  # (sealed in place as read, h538: a later process reads them quietly)
        f"tlm: warning: reference cache entry {folders[0]} was written by an older tlm, its meta.json without "
        f"'{META_SEAL}' (a digest of its own): sealed as read, so a value changed in it from now on is told (one "
        "changed before cannot be: 'tlm reference --force' computes it again, sealed)",
        f"tlm: warning: Mitsuba ground-truth cache entry {folders[1]} was written by an older tlm, its meta.json "
        f"without '{META_SEAL}' (a digest of its own): sealed as read, so a value changed in it from now on is told "
        f"(one changed before cannot be: removing {folders[1]} renders it again, sealed)"], said
    assert all(f.exists() for f in folders)


def test_another_tlms_format_is_computed_again_quietly_and_a_held_meta_is_sealed_anew(cache, capsys):
    folder = _reference()
    meta = json.loads((folder / "meta.json").read_text())
    (folder / "meta.json").write_text(json.dumps(sealed({**meta, "format": "reference-meta/3"}, META_SEAL)))
    capsys.readouterr()
    assert rc.load_reference(folder.name) is None and folder.exists()  # (not removed: replaced when computed)
    assert not _warnings(capsys.readouterr().err)
    # a meta read back (its digest and format in it: a sweep's own copy, sweep_reference) saved again is sealed anew
    rc.save_reference(folder.name, np.ones((4, 6, 3)), {**meta, "rounds": 12})
    got = rc.load_reference(folder.name)
    assert got is not None and got[1]["rounds"] == 12 and got[1]["format"] == "reference-meta/2"
    assert not _warnings(capsys.readouterr().err)
