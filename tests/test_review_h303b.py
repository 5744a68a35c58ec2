"""(review h303) A sweep whose programs table is a pipe is refused in one line, exit 2,
writing nothing: its points read the table in processes of their own (each 'file not found', exit 1)."""

import os
from pathlib import Path

from tlm.arch.costs import DEFAULT_PATH


def test_a_sweep_with_a_programs_table_from_a_pipe_is_refused_in_one_line(tmp_path, monkeypatch, cache, capsys):
    from tlm.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "b.yaml").write_text("scene: cornell\nmode: rcast\nresolution: [8, 8]\n")
    (tmp_path / "sw.yaml").write_text("base: b.yaml\ngrid:\n  arch.pipelines: [1, 2]\n")
    r, w = os.pipe()
    os.write(w, DEFAULT_PATH.read_bytes())
    os.close(w)
    try:
        rc = main(["sweep", "sw.yaml", "--set", f"arch.programs=/dev/fd/{r}", "--out", "o", "--no-progress",
                   "--no-report"])
    finally:
        os.close(r)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert f"/dev/fd/{r}: arch.programs: is no file but a pipe" in err, err
    assert not Path("o").exists()
