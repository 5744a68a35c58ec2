"""h473: two messages that left the user guessing (h466's probe).

* A photon-map reference that misses its tolerance said "raise reference.max_rounds" with no number: each such
  line (``tlm reference``'s, the run warning's, the cached one kept by ``tlm reference`` and ``tlm sweep
  --reference``) now estimates it, rounds x (rse / tolerance)^2 in whole cycles (the standard error falls as
  1/sqrt(rounds)): 648 for h466's 40x30 reference (rse 0.045 after 128 rounds), which, run, converged after 572.
* ``tlm granularity RUNCONFIG`` refused the run config without saying what to write: it now gives the two-line
  study file, which runs.
"""

from __future__ import annotations

import tlm
from tlm.cli import main
from tlm.config_sections import ReferenceConfig
from tlm.experiments import run_warnings
from tlm.experiments.granularity import load_granularity
from tlm.experiments.reference import rounds_advice
from tlm.experiments.reference_cache import ReferenceSettings


def test_the_advice_estimates_the_rounds_in_whole_cycles():
    settings = ReferenceSettings(photons=20000)  # (tolerance 0.02, cycles of 4 rounds)
    assert rounds_advice(0.045, 128, settings).startswith(" to about 648 (128 rounds x (0.0450 / 0.02)^2 in whole "
                                                          "cycles of 4")
    assert rounds_advice(0.0451, 128, settings).startswith(" to about 652 ")  # (650.9: up to a whole cycle)
    assert rounds_advice(0.045, 128, ReferenceConfig()).startswith(" to about 648 ")  # (a run config's section)
    assert rounds_advice(0.01, 128, settings) == ""  # (below the tolerance: min_rounds, not max_rounds)
    assert rounds_advice(None, 128, settings) == rounds_advice(0.05, None, settings) == ""
    far = rounds_advice(0.1, 4, ReferenceConfig(tolerance=1e-6, max_rounds=4, spp=1))
    assert "past its limit 10000: raise reference.tolerance instead" in far and "about 4e+10 rounds" in far


def test_the_run_warning_says_how_many_rounds():
    cfg = tlm.load_config("cornell", {"mode": "pmap"}).settings
    error = {"available": True, "reference_converged": False, "reference": "abc", "reference_rounds": 128,
             "reference_standard_error": 0.045}
    [line] = run_warnings.reference_warnings(error, cfg)
    assert "raise reference.max_rounds to about 648 (128 rounds x (0.0450 / 0.02)^2" in line, line
    assert line.endswith("and compute it again with 'tlm reference'")


def test_tlm_reference_not_converged_says_how_many_rounds(tmp_path, capsys, cache):
    small = ["resolution=[8, 8]", "reference.photons=2000", "reference.k_nearest=20", "reference.spp=1",
             "reference.max_rounds=4", "reference.tolerance=0.05"]
    assert main(["reference", "cornell", "--no-progress", *[f"--set={s}" for s in small]]) == 1
    [last] = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("NOT converged")]
    assert "(raise reference.max_rounds to about " in last and "in whole cycles of 1" in last, last
    assert last.endswith(", or reference.tolerance; exit status 1)")


def test_granularity_of_a_run_config_gives_the_study_file_to_write(tmp_path, capsys):
    run = tmp_path / "exp1.yaml"
    run.write_text("scene: cornell\nmode: rcast\nseed: 1\n")
    assert main(["granularity", str(run), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a granularity study file: run it with tlm run" in err
    assert "write a study file of two lines beside it, 'base: exp1.yaml' and 'packet_sizes: [1, 16, 256, 4096]'" in err
    study = tmp_path / "gran.yaml"  # (the file it gives, written: it loads, the run config as its base)
    study.write_text("base: exp1.yaml\npacket_sizes: [1, 16, 256, 4096]\n")
    cfg, sizes, _ = load_granularity(study)
    assert sizes == [1, 16, 256, 4096] and cfg.seed == 1 and cfg.mode == "rcast"
    assert not (tmp_path / "o").exists()
