"""``tlm run --set arch.programs=FILE``: a relative instruction-cost table given on the command
line is read from the working folder (tests/test_programs_path.py, tests/test_api_programs_path.py)."""

from __future__ import annotations

import json
from pathlib import Path

import tlm
from tlm.cli import main

PACKAGED = Path(tlm.__file__).parent / "arch" / "programs.yaml"
TINY_SET = ["--set", "resolution=[8,8]", "--set", "mode=rcast", "--set", "render.spp=1",
            "--set", "render.light_samples=1", "--set", "arch.trace=false"]


def tlm_run_reads_the_working_folders_table(capsys, config: str, table: str, work: Path) -> None:
    """``tlm run CONFIG --set arch.programs=TABLE`` (8x8, one sample) from the working folder
    ``work`` records ``work/TABLE`` as its table; with ``arch.programs=nope.yaml`` (not in ``work``)
    it stops with one error line naming ``work/nope.yaml``, and writes no output folder."""
    assert main(["run", config, "--set", f"arch.programs={table}", *TINY_SET, "--out", "out",
                 "--no-progress", "--no-report"]) == 0
    results = json.loads((work / "out" / "results.json").read_text())
    assert results["timing"]["programs"]["source"] == str(work / table)
    capsys.readouterr()
    assert main(["run", config, "--set", "arch.programs=nope.yaml", *TINY_SET, "--out", "out2",
                 "--no-progress", "--no-report"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("tlm: error")]
    assert err == [f"tlm: error: {work / 'nope.yaml'}: arch.programs: file not found"]
    assert not (work / "out2").exists()
