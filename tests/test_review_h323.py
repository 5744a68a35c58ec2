"""Review of a53bda9 (h323): a cache that a full disk stops writing is said once, not once a frame.

a53bda9 let a cache's line be said again whenever its text changed. A failed write into the functional cache
told it twice: :mod:`tlm.storage`'s hearer with the machine's words (``no space left on device``), then the
frame's writer with the :class:`~tlm.errors.EnvironmentFailure` that storage raised, naming the entry
(``<folder>/<key>.npz: cannot write: ...``): a new line for every frame, a sweep's point and a run said one each.
"""

from __future__ import annotations

import builtins
import errno

import yaml

from tlm import api, caches, storage
from tlm.config import config_from_dict
from tlm.errors import EnvironmentFailure
from tlm.experiments import frames

FRAME = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}}


def _full_disk(monkeypatch, folder) -> None:
    """Every file tlm.storage opens for writing under ``folder`` fails as on a full disk."""
    real = builtins.open

    def fake(path, mode="r", *args, **kwargs):
        if str(path).startswith(f"{folder}/") and any(c in mode for c in "wax"):
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, mode, *args, **kwargs)

    monkeypatch.setattr(storage, "open", fake, raising=False)


def _lines(text: str, folder) -> list[str]:
    return [line for line in text.splitlines() if f"cannot write tlm's functional cache {folder} (" in line]


def test_a_full_disk_is_said_once_for_many_frames(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "c"))
    folder = caches.cache_root("functional")
    _full_disk(monkeypatch, folder)
    for seed in (1, 2, 3):
        assert frames.cached_render(config_from_dict({**FRAME, "seed": seed}, "x.yaml")).cached is False
    said = _lines(capsys.readouterr().err, folder)
    assert len(said) == 1 and f"{folder} (no space left on device): " in said[0], said  # (no entry named)
    assert [w for w in caches.cache_warnings() if str(folder) in w] == [said[0].removeprefix("tlm: warning: ")]
    assert not list(folder.glob("*.npz"))


def test_a_write_cut_short_by_other_sizes_is_one_line(tmp_path, monkeypatch, capsys):
    """numpy's short write (no errno) names its sizes, which differ from frame to frame: one line still."""
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "c"))
    folder = caches.cache_root("functional")
    for n in (1000, 2000):
        cause = OSError(f"{n} requested and {n // 2} written")
        try:
            raise EnvironmentFailure("cannot write: no space", source=str(folder / f"{n}.npz")) from cause
        except EnvironmentFailure as e:
            caches.cache_write_failed(folder / f"{n}.npz", e)  # (the writer's, naming its entry: its cause said)
            caches.cache_write_failed(folder / f"{n}.npz", cause)  # (tlm.storage's hearer's)
    said = _lines(capsys.readouterr().err, folder)
    assert len(said) == 1 and "1000 requested and 500 written" in said[0], said
    assert len([w for w in caches.cache_warnings() if str(folder) in w]) == 1


def test_a_sweep_on_a_full_disk_records_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("TLM_CACHE", str(tmp_path / "c"))
    folder = caches.cache_root("functional")
    _full_disk(monkeypatch, folder)
    (tmp_path / "sw.yaml").write_text(yaml.safe_dump({"base": FRAME, "grid": {"seed": [1, 2, 3]}}))
    got: list[str] = []
    done = api.run_sweep(tmp_path / "sw.yaml", tmp_path / "out", jobs=1, warn=got.append)
    assert len([w for w in done.warnings if str(folder) in w]) == 1, done.warnings
    assert len([w for w in got if str(folder) in w]) + len(_lines(capsys.readouterr().err, folder)) == 1
