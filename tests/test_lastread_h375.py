"""The last read of the change 2092941.. (h375): what two of its commits did not see of each other.

* ``sweep.csv``'s ``scene`` of a ``--set scene`` is the path as given (h143), read by the sweep's own
  ``_set_scene`` with plain ``yaml.safe_load``, which refuses a byte not UTF-8 (``scene=dir_\\xff/box.yaml``:
  ``unacceptable character #xdcff``), though the run's ``--set`` reads it since h370
  (:func:`tlm.config.read_set_value`): the row then named the file by its path from the sweep file's folder
  (``../work/dir_\\xff/box.yaml``), not as given.
"""

from __future__ import annotations

import os

import yaml

from tlm.experiments.sweep import _set_scene, run_sweep

DIR = os.fsdecode(b"dir_\xff")  # (dir_\udcff, as the command line reads it)
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1},
        "arch": {"frames": 1, "trace": False, "packet_size": 32}}


def test_the_sweeps_set_scene_is_read_as_a_runs_set_reads_it():
    assert _set_scene([f"scene={DIR}/box.yaml", "render.spp=2"]) == f"{DIR}/box.yaml"  # (was: None)
    assert _set_scene(["scene='3'"]) == "3"  # (YAML's syntax read as before)
    assert _set_scene(["scene=[unclosed"]) is None


def test_sweep_csv_names_a_set_scene_in_a_folder_not_utf8_as_given(tmp_path, elsewhere, cache):
    sweeps = tmp_path / "sweeps"
    sweeps.mkdir()
    (sweeps / "base.yaml").write_text(yaml.safe_dump(BASE))
    path = sweeps / "s.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "grid": {"arch.pipelines": [1, 2]}}))
    (elsewhere / DIR).mkdir()
    (elsewhere / DIR / "box.yaml").write_text("extends: cornell\nname: my box\n")
    done = run_sweep(path, tmp_path / "o", jobs=1, overrides=[f"scene={DIR}/box.yaml"])
    assert [r["scene"] for r in done.rows] == [f"{DIR}/box.yaml"] * 2  # (was: ../work/dir_\udcff/box.yaml)
