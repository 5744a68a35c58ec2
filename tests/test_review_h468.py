"""h468: a review of h464 (a rerun keeps a file tlm wrote that the user edited since).

* A folder copied without its files' times (``cp -r``, an archive's, a file system of coarser times) had every
  file "changed since": a rerun into the copy named each file it wrote again as the user's it replaced ("'aov/...',
  ... and 8 more (yours: ...)"), none edited, and kept each it did not write again as the user's. Where no file the
  listing names has its listed time, the times tell nothing: sizes alone tell an edited file.
* A folder with no listing kept an earlier output's folder that the new output does not write at all (a run's
  ``radiance/`` under ``--outputs images``) file by file, the warning naming each, and nothing said that a report
  reads it as the new output's (tlm run's report rebuilt its images from the earlier run's radiance): it is named
  whole now, and the warning says so.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from tlm.cli import main
from tlm.storage import atomic_folder
from tlm.storage_carry import LISTING

CORNELL = str(Path(__file__).resolve().parents[1] / "configs" / "cornell.yaml")
RUN = ["run", CORNELL, "--set", "resolution=[8,8]", "--no-report", "--no-progress"]


def _output(out: Path, files: dict[str, str], owned=("m", "t.json", "images", "aov", "radiance")) -> None:
    """An output of ``files`` (``m``, the marker, among them) written into ``out`` by :func:`atomic_folder`."""
    with atomic_folder(out, "m", owned=owned) as tmp:
        for rel, text in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_text(text)


def _files(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): p.read_text(errors="replace") for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != LISTING}


def _copy_without_times(src: Path, dst: Path) -> None:
    """``cp -r``: every file's modification time another (a second later: no test depends on the clock)."""
    shutil.copytree(src, dst, copy_function=shutil.copyfile)
    for p in dst.rglob("*"):
        if p.is_file():
            was = os.stat(src / p.relative_to(dst)).st_mtime_ns
            os.utime(p, ns=(was + 10**9, was + 10**9))


def test_a_copy_without_times_tells_the_user_s_edits_by_their_size(tmp_path, capsys):
    out, copy = tmp_path / "o", tmp_path / "copy"
    _output(out, {"m": "1", "t.json": "{}", "images/a.png": "1", "images/old.png": "1", "aov/w.npz": "1"})
    _copy_without_times(out, copy)
    (copy / "aov" / "w.npz").write_text("annotated")  # (another size: the user's)
    capsys.readouterr()
    _output(copy, {"m": "2", "t.json": "{}", "images/a.png": "2"})
    assert _files(copy) == {"m": "2", "t.json": "{}", "images/a.png": "2", "aov/w.npz": "annotated"}
    assert "warning" not in capsys.readouterr().err
    # the copy's own listing has the times: a same-size edit is told again
    was = os.stat(copy / "images" / "a.png").st_mtime_ns
    (copy / "images" / "a.png").write_text("3")
    os.utime(copy / "images" / "a.png", ns=(was + 10**9, was + 10**9))
    _output(copy, {"m": "3", "images/a.png": "4"})
    assert "'images/a.png' (yours" in capsys.readouterr().err


def test_a_rerun_of_tlm_run_into_a_copy_of_its_folder_says_nothing(tmp_path, cache, capsys):
    out, copy = tmp_path / "r", tmp_path / "copy"
    assert main([*RUN, "--out", str(out)]) == 0
    _copy_without_times(out, copy)
    capsys.readouterr()
    assert main([*RUN, "--out", str(copy), "--outputs", "images"]) == 0
    assert "yours" not in capsys.readouterr().err
    assert sorted(os.listdir(copy)) == [LISTING, "config.resolved.yaml", "images", "results.json"]


def test_a_folder_with_no_listing_keeps_one_the_new_output_does_not_write_whole_and_says_a_report_reads_it(
        tmp_path, capsys):
    out = tmp_path / "o"
    _output(out, {"m": "1", "images/a.png": "1", "images/b.png": "1",
                  **{f"radiance/p{i}.npy": "1" for i in range(200)}})
    (out / LISTING).unlink()
    capsys.readouterr()
    _output(out, {"m": "2", "images/a.png": "2"})
    assert len(_files(out)) == 203
    (line,) = [x for x in capsys.readouterr().err.splitlines() if "warning" in x]
    assert "yours: 'images/b.png' and 'radiance', which this output does not write, were kept as yours" in line
    assert "it is not this output's; a report leaves out what the output's listing does not name" in line
