"""The ``cache`` config section: declared, listed, checked where it enters, in the cache key.

Bad values go through ``tlm run`` like every case of ``test_bad_input.py``: exit 2, one
line on stderr naming the file and the key, nothing written.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.config import config_from_dict, describe, to_dict
from tlm.experiments.frames import functional_key, render_key

CONFIG = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"light_samples": 1}}


def test_the_section_is_declared_with_the_thesis_defaults(capsys):
    cfg = config_from_dict({})
    assert (cfg.cache.pairs, cfg.cache.block_words) == (4, 1024)
    keys = {key: (default, help_text) for key, default, help_text in describe()}
    assert keys["cache.pairs"][0] == 4 and keys["cache.block_words"][0] == 1024
    assert all(keys[k][1] for k in ("cache.pairs", "cache.block_words"))
    assert main(["params"]) == 0
    out = capsys.readouterr().out
    assert "cache.pairs" in out and "cache.block_words" in out
    cfg = config_from_dict({"cache": {"pairs": 1, "block_words": 4096}})
    assert (cfg.cache.pairs, cfg.cache.block_words) == (1, 4096)


@pytest.mark.parametrize(("cache", "expect"), [
    ({"pairs": 0}, ("cache.pairs", "0", ">= 1")),
    ({"pairs": 5}, ("cache.pairs", "5", "<= 4")),
    ({"pairs": 2.5}, ("cache.pairs", "2.5")),
    ({"block_words": 1.5}, ("cache.block_words", "1.5")),
    ({"block_words": 1}, ("cache.block_words", "1", ">= 3")),
    ({"block_words": "big"}, ("cache.block_words", "big is not an integer")),
    ({"pair": 2}, ("cache.pair", "unknown key", "did you mean 'pairs'")),
    (7, ("cache", "7")),
], ids=["pairs-0", "pairs-5", "pairs-float", "block-1.5", "block-1", "block-str", "unknown-key", "not-mapping"])
def test_bad_cache_values_exit_2_with_one_line(tmp_path: Path, capsys, cache, expect):
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump({**CONFIG, "cache": cache}))
    before = set(tmp_path.rglob("*"))
    code = main(["run", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("tlm: error: ") and "Traceback" not in err
    for s in ("cfg.yaml", *expect):
        assert s in lines[0], (s, lines[0])
    assert set(tmp_path.rglob("*")) == before  # nothing written


def test_bad_cache_override_names_the_key(tmp_path: Path, capsys):
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(CONFIG))
    code = main(["run", str(tmp_path / "cfg.yaml"), "--out", str(tmp_path / "out"), "--set", "cache.pairs=0"])
    line = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in line and "cache.pairs" in line and "--set" in line


def test_the_functional_cache_key_covers_the_section():
    base = config_from_dict(CONFIG)
    keys = {render_key(config_from_dict({**CONFIG, "cache": c}))
            for c in ({}, {"pairs": 1}, {"pairs": 1, "block_words": 256}, {"block_words": 256})}
    assert len(keys) == 4
    assert render_key(base) == render_key(config_from_dict({**CONFIG, "cache": {"pairs": 4, "block_words": 1024}}))
    d = to_dict(base)
    other = {**d, "cache": {**d["cache"], "pairs": 1}}
    assert functional_key(d, "scene", "code") != functional_key(other, "scene", "code")
