"""``tlm run myroom`` where ``myroom.yaml`` lies in the working folder: the error names that file and the
command that runs it (before: the list of built-in experiments alone, and a did-you-mean among them)."""

from __future__ import annotations

import pytest

from tlm.builtin import experiment_path
from tlm.errors import InputError


@pytest.mark.parametrize("suffix", [".yaml", ".yml"])
def test_a_name_whose_yaml_file_is_here_names_it(tmp_path, monkeypatch, suffix):
    monkeypatch.chdir(tmp_path)
    (tmp_path / f"myroom{suffix}").write_text("scene: cornell\n")
    with pytest.raises(InputError) as caught:
        experiment_path("myroom", "sweep")
    assert str(caught.value).endswith(f"a file myroom{suffix} is here: tlm sweep myroom{suffix}"), caught.value


def test_a_name_with_no_file_here_keeps_its_did_you_mean(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as caught:
        experiment_path("cornel")
    assert "is here" not in str(caught.value) and "cornell" in str(caught.value)
