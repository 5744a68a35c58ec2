"""The last read of the stop's whole change: what it found, pinned."""

import yaml

from tlm.arch import costs


def test_a_table_written_before_photons_weighted_is_read_with_it_at_0_and_said(tmp_path, capsys):
    """A programs table written before the cone weight was counted apart (no photons_weighted) keeps its costs: the
    item is read as 0 (its photons_accepted priced the weight), with one warning, not refused in every mode."""
    table = yaml.safe_load(costs.DEFAULT_PATH.read_text())
    del table["fragment"]["gather"]["instructions"]["photons_weighted"]
    table["fragment"]["gather"]["instructions"]["photons_accepted"] = 8  # (as such a table priced it)
    old = tmp_path / "old.yaml"
    old.write_text(yaml.safe_dump(table))
    got = costs.load_programs(old)
    job = got.jobs[("fragment", "gather")]
    assert job.instructions["photons_weighted"] == 0.0 and job.instructions["photons_accepted"] == 8
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tlm: warning: ") and "prices no 'photons_weighted'" in err[0], err
    assert "keeps its costs" in err[0]
