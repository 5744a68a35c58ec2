"""``tlm run``'s own ``results.json`` records the line on a cache of tlm's it cannot write
(``cannot write tlm's reference cache ...``), as a sweep's points do: it was said on stderr
and missing from the run's ``warnings``. A path under a regular file stands for a cache
folder that cannot be made, even for root."""

from __future__ import annotations

import json

from tlm import api

PMAP = {"scene": "cornell", "mode": "pmap", "resolution": [8, 8], "render": {"spp": 1}, "photons": {"count": 500}}


def test_a_run_s_results_record_the_cache_it_could_not_write(tmp_path, monkeypatch, capsys):
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    monkeypatch.setenv("TLM_CACHE", str(afile / "cache"))
    results = api.run(PMAP, tmp_path / "run", outputs=(), reference=False)  # (the reference cache: looked up)
    said = [line.removeprefix("tlm: warning: ") for line in capsys.readouterr().err.splitlines()
            if line.startswith("tlm: warning: cannot write tlm's ")]
    assert said == [f"cannot write tlm's reference cache {afile / 'cache' / 'references'} ({afile} is a file, not a "
                    "folder): photon-map references are computed again by every run; set TLM_CACHE to a writable "
                    "folder"], said
    assert said[0] in results["warnings"]
    assert json.loads((tmp_path / "run" / "results.json").read_text())["warnings"] == results["warnings"]
    assert results["warnings"].count(said[0]) == 1
