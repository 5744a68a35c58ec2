"""h371: review of 46665b7 (errors.quoted) and 49c29bc (the liveness bound that grows; arch.settle_frames judged
from the run).

* ``tlm calibrate``'s refusals named the study's scenes and modes by ``repr`` (``['dir_\\udcff/cornell.yaml']``),
  not by :func:`tlm.errors.quoted` (``\\xff``), which 46665b7 left out;
* :func:`tlm.errors.quoted` (and ``api_common.shown``, which quotes a bad argument by it) raised where a path
  object's ``__fspath__`` fails or gives no text, in place of the message about that value.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tlm.api_common import shown
from tlm.errors import InputError, quoted
from tlm.experiments.thesis import calibrate

REPO = Path(__file__).resolve().parents[1]
DIR = os.fsdecode(b"dir_\xff")  # (dir_\udcff)


class _NoText(os.PathLike):
    def __fspath__(self):
        return 3


class _Fails(os.PathLike):
    def __fspath__(self):
        raise RuntimeError("no path")

    def __repr__(self):
        return "<a path that fails>"


def test_quoted_never_raises_for_a_path_object_without_text():
    assert quoted(_Fails()) == "<a path that fails>" and shown(_Fails()) == "<a path that fails>"
    assert quoted(_NoText()).startswith("<") and "_NoText" in shown(_NoText())


def _study(tmp_path: Path, body: str) -> Path:
    (tmp_path / DIR).mkdir()
    (tmp_path / DIR / "cornell.yaml").write_text((REPO / "scenes" / "cornell.yaml").read_text(encoding="utf-8"),
                                                 encoding="utf-8")
    (tmp_path / DIR / "mine.yaml").write_text((REPO / "scenes" / "cornell.yaml").read_text(encoding="utf-8")
                                              .replace("vfov: 39.3", "vfov: 40"), encoding="utf-8")  # (not cornell's)
    study = tmp_path / "study.yaml"
    study.write_text(body, encoding="utf-8")
    return study


@pytest.mark.parametrize(("scenes", "said"), [
    ('["dir_\\udcff/cornell.yaml"]', "['dir_\\xff/cornell.yaml']: one scene gives one RCast cell per PM"),
    ('["dir_\\udcff/mine.yaml"]', "['dir_\\xff/mine.yaml'] have no thesis table"),
])
def test_calibrate_names_its_scenes_as_a_tlm_line_does(tmp_path, scenes, said):
    study = _study(tmp_path, f"base: {{resolution: [8, 8]}}\nscenes: {scenes}\nmodes: [rcast]\n")
    with pytest.raises(InputError) as err:
        calibrate(study)
    assert said in str(err.value) and "\\udc" not in str(err.value), str(err.value)


def test_calibrate_names_its_modes_as_a_tlm_line_does(tmp_path):
    study = _study(tmp_path, 'base: {resolution: [8, 8]}\nscenes: [cornell]\nmodes: ["pmap\\udcff"]\n')
    with pytest.raises(InputError) as err:
        calibrate(study)
    assert "modes: ['pmap\\xff'] must be a non-empty list" in str(err.value), str(err.value)


def test_a_stream_stopped_below_both_caps_is_no_mismatch_however_its_estimate_reads():
    """arch.settle_frames beside a thesis table (49c29bc): a stream that ran on and stopped below its cap stopped
    where its completions so far repeated, which each arrival decides alike at any cap from there on; the
    whole stream's estimate (``settled``, over the gaps before the drain) does not change that, as
    run_warnings.timing_inert judges it (the run's own warning said the key had no effect, Table III that it
    made the cell not comparable)."""
    import copy

    from tlm.experiments.thesis_setting import setting_mismatches, thesis_setting

    ours = copy.deepcopy(thesis_setting("cornell", "pmap"))
    ours["arch"]["settle_frames"] = 32
    timing = {"frames": 20, "frames_asked": 5,
              "throughput_estimate": {"frames": 20, "window": [1, 17], "frames_cap": 32, "settled": False}}
    assert setting_mismatches("cornell", ours, timing) == []
    timing["frames"] = 32  # (cut by its cap: the thesis's 64 might have run on)
    assert setting_mismatches("cornell", ours, timing) == [
        "arch.settle_frames 32 (configs/thesis.yaml: 64; not in the thesis)"]
